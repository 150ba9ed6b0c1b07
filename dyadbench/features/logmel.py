"""Log-mel speech features aligned to motion frames: the default speech frontend (no download).

One feature row per motion frame: hop = sample_rate / fps samples (640 at 16 kHz / 25 fps), a Hann
window of ``win_length`` samples centred on the frame's centre, zero-padded at the edges of the given
audio, ``n_mels`` triangular mel bands (HTK mel scale) between ``fmin`` and ``fmax``, natural log of
power + 1e-6. Computing it on a 1-s chunk uses only that chunk, so per-turn features are causal.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from dyadbench.errors import InputError

LOG_FLOOR = 1e-6


def hz_to_mel(hz: np.ndarray | float) -> np.ndarray:
    """HTK mel scale: m = 2595 log10(1 + f / 700)."""
    return 2595.0 * np.log10(1.0 + np.asarray(hz, dtype=np.float64) / 700.0)


def mel_to_hz(mel: np.ndarray | float) -> np.ndarray:
    return 700.0 * (10.0 ** (np.asarray(mel, dtype=np.float64) / 2595.0) - 1.0)


@lru_cache(maxsize=16)
def mel_filterbank(sample_rate: int, n_fft: int, n_mels: int, fmin: float, fmax: float) -> np.ndarray:
    """(n_mels, n_fft // 2 + 1) triangular filters, each normalised to unit area (Slaney-style)."""
    freqs = np.linspace(0.0, sample_rate / 2.0, n_fft // 2 + 1)
    edges = mel_to_hz(np.linspace(hz_to_mel(fmin), hz_to_mel(fmax), n_mels + 2))
    lower, centre, upper = edges[:-2, None], edges[1:-1, None], edges[2:, None]
    rising = (freqs[None, :] - lower) / (centre - lower)
    falling = (upper - freqs[None, :]) / (upper - centre)
    bank = np.clip(np.minimum(rising, falling), 0.0, None)
    bank *= (2.0 / (upper - lower))
    bank.setflags(write=False)
    return bank


@lru_cache(maxsize=16)
def _hann(win_length: int) -> np.ndarray:
    window = np.hanning(win_length)
    window.setflags(write=False)
    return window


def logmel_frames(audio: np.ndarray, sample_rate: int = 16_000, fps: float = 25.0, *, n_mels: int = 40,
                  win_length: int = 1024, fmin: float = 60.0, fmax: float | None = None) -> np.ndarray:
    """Log-mel features, one row per motion frame: (floor(len(audio) * fps / sample_rate), n_mels) float32.

    .. math:: F_{t,m} = \\log\\Big(\\sum_f B_{m,f} \\, |\\mathrm{STFT}(w \\cdot x)_{t,f}|^2 / N + 10^{-6}\\Big)
    """
    audio = np.asarray(audio)
    if audio.ndim != 1:
        raise InputError(None, f"log-mel features need mono audio (S,), got shape {audio.shape}")
    hop = sample_rate / fps
    if abs(hop - round(hop)) > 1e-9:
        raise InputError(None, f"sample_rate / fps must be an integer hop, got {sample_rate}/{fps}")
    hop = int(round(hop))
    n_frames = len(audio) // hop
    if n_frames == 0:
        return np.zeros((0, n_mels), dtype=np.float32)
    fmax = sample_rate / 2.0 if fmax is None else fmax
    half = win_length // 2
    padded = np.pad(audio.astype(np.float64), (half, half + hop))
    centres = np.arange(n_frames) * hop + hop // 2 + half
    idx = centres[:, None] + np.arange(-half, win_length - half)[None, :]
    frames = padded[idx] * _hann(win_length)[None, :]
    power = np.abs(np.fft.rfft(frames, n=win_length, axis=1)) ** 2 / win_length
    mel = power @ mel_filterbank(sample_rate, win_length, n_mels, fmin, fmax).T
    return np.log(mel + LOG_FLOOR).astype(np.float32)


def rms_envelope(audio: np.ndarray, sample_rate: int = 16_000, fps: float = 25.0) -> np.ndarray:
    """Root-mean-square of the audio in each motion frame's hop: (len(audio) * fps // sample_rate,)."""
    hop = int(round(sample_rate / fps))
    n = len(audio) // hop
    chunks = np.asarray(audio[: n * hop], dtype=np.float64).reshape(n, hop)
    return np.sqrt(np.mean(chunks ** 2, axis=1))
