"""Speech-like audio and the speech signals that drive motion, from a participant's :class:`Track`.

Signals live on a fine grid of 400 Hz (16 steps per 25-fps frame, 40 samples at 16 kHz):

- envelope: each syllable is a sin^2 bump of its amplitude over its duration (syllable rate 4-6 Hz);
- pitch f0: the speaker's base pitch x phrase declination (+8 % at phrase start to -8 % at its end)
  x a pitch accent (+``f0_accent`` sin bump) on emphasised syllables x a slight 4.7 Hz vibrato;
- vowel openness: per syllable, between an open "a" and a spread "i" timbre.

Audio = near-silence everywhere (white Gaussian floor at -60 dBFS, sliced from a fixed table at random
offsets), plus, inside phrases, ``loudness`` x envelope x a harmonic wavetable oscillator following f0
(harmonics with roll-off ``timbre_tilt`` and two vowel-dependent formant peaks, cross-faded by vowel
openness) and a 10-ms decaying noise burst at each syllable onset (a consonant). Samples are quantised to the 16-bit PCM grid so a written
wav reads back exactly.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from dyadbench.datasets.wav import float_to_pcm16, pcm16_to_float
from dyadbench.features.activity import segments_mask
from dyadbench.seeding import rng as seeded_rng
from dyadbench.synth.signals import block_mean, upsample_linear
from dyadbench.synth.styles import Style
from dyadbench.synth.timeline import Track

FINE_RATE = 400  # Hz
TABLE_SIZE = 4096
NOISE_FLOOR = 1e-3  # RMS of the silence floor (-60 dBFS)
NOISE_TABLE_SIZE = 1 << 20
BURST_GAIN, BURST_DECAY_S = 0.25, 0.01  # consonant noise burst at each syllable onset
FORMANTS = {"a": (750.0, 1250.0), "i": (300.0, 2300.0)}


@dataclass(frozen=True)
class SpeechSignals:
    """Frame-rate (25 fps) speech signals of one participant, plus its audio."""

    speaking: np.ndarray  # (T,) bool: frame centre inside one of the participant's phrases
    envelope: np.ndarray  # (T,) mean syllable envelope in the frame (0 when silent)
    vowel: np.ndarray  # (T,) vowel openness weighted by envelope (0..1)
    pitch: np.ndarray  # (T,) relative pitch deviation f0 / f0_base - 1 while voiced, else 0
    audio: np.ndarray  # (T * hop,) float32 on the PCM16 grid


def _fine_signals(track: Track, style: Style, n_fine: int) -> tuple[np.ndarray, ...]:
    """Envelope, f0 (Hz), vowel openness and consonant-burst envelope on the fine grid: (n_fine,) each."""
    env, vowel, burst = np.zeros(n_fine), np.zeros(n_fine), np.zeros(n_fine)
    f0 = np.full(n_fine, style.f0_base)
    if len(track.onset) == 0:
        return env, f0, vowel, burst
    tf = (np.arange(n_fine) + 0.5) / FINE_RATE
    idx = np.searchsorted(track.onset, tf, side="right") - 1
    valid = idx >= 0
    i = np.where(valid, idx, 0)
    u = (tf - track.onset[i]) / track.dur[i]
    valid &= u < 1.0
    bump = np.sin(np.pi * np.clip(u, 0.0, 1.0))
    env = np.where(valid, track.amp[i] * bump ** 2, 0.0)
    ph = track.phrase_of[i]
    start, end = track.phrases[ph, 0], track.phrases[ph, 1]
    pos = np.clip((tf - start) / np.maximum(end - start, 1e-3), 0.0, 1.0)
    accent = np.where(valid & track.emph[i], style.f0_accent * bump, 0.0)
    f0 = style.f0_base * (1.08 - 0.16 * pos) * (1.0 + accent) * (1.0 + 0.015 * np.sin(2 * np.pi * 4.7 * tf))
    f0 = np.where(valid, f0, style.f0_base)
    vowel = np.where(valid, track.vowel[i], 0.0)
    since_onset = np.where(valid, tf - track.onset[i], np.inf)
    burst = BURST_GAIN * track.amp[i] * np.exp(-since_onset / BURST_DECAY_S)
    return env, f0, vowel, burst


def wavetables(style: Style, sample_rate: int) -> np.ndarray:
    """(2, TABLE_SIZE) one-period waveforms of the voice for vowels "a" and "i" (unit RMS).

    Table v is sum_k w_k sin(2 pi k n / N) with w_k = k^-tilt x (1 + 4 G(k f0 - F1, 200) + 2.5 G(k f0 - F2, 300)),
    G(x, s) = exp(-(x / s)^2), for the vowel's formants F1, F2, built by an inverse real FFT.
    """
    n_harm = int(min(40, (0.45 * sample_rate) / style.f0_base))
    k = np.arange(1, n_harm + 1)
    freq = k * style.f0_base
    tables = []
    for f1, f2 in FORMANTS.values():
        w = k ** (-style.timbre_tilt) * (1.0 + 4.0 * np.exp(-((freq - f1) / 200.0) ** 2)
                                         + 2.5 * np.exp(-((freq - f2) / 300.0) ** 2))
        spectrum = np.zeros(TABLE_SIZE // 2 + 1, dtype=np.complex128)
        spectrum[k] = -0.5j * TABLE_SIZE * w
        table = np.fft.irfft(spectrum, n=TABLE_SIZE)
        tables.append(table / np.sqrt(np.mean(table ** 2)))
    return np.asarray(tables, dtype=np.float32)


@lru_cache(maxsize=1)
def _noise_table() -> np.ndarray:
    """A fixed 2^20-sample white Gaussian table (unit variance) that noise is sliced from."""
    return seeded_rng("dyadbench-synth-noise").standard_normal(NOISE_TABLE_SIZE, dtype=np.float32)


def _noise(r: np.random.Generator, n: int) -> np.ndarray:
    """``n`` samples of unit white noise from a random offset of the table (wrapping around)."""
    table = _noise_table()
    pos = int(r.integers(NOISE_TABLE_SIZE))
    parts = []
    while n > 0:
        take = min(n, NOISE_TABLE_SIZE - pos)
        parts.append(table[pos:pos + take])
        n, pos = n - take, 0
    return np.concatenate(parts) if parts else np.zeros(0, dtype=np.float32)


def _synthesise(r: np.random.Generator, style: Style, env: np.ndarray, f0: np.ndarray, vowel: np.ndarray,
                burst: np.ndarray, phrases: np.ndarray, n_samples: int, sample_rate: int) -> np.ndarray:
    step = sample_rate // FINE_RATE
    audio = _noise(r, n_samples) * np.float32(NOISE_FLOOR)
    table_a, table_i = wavetables(style, sample_rate)
    table_diff = table_i - table_a
    frac = (np.arange(step) / step).astype(np.float32)
    for start, end in phrases:
        k0, k1 = int(start * FINE_RATE), min(len(env), int(np.ceil(end * FINE_RATE)) + 1)
        if k1 <= k0:
            continue
        s0, s1 = k0 * step, k1 * step
        # phase in cycles: exact sum over fine steps, linear inside each step (constant f0 per 2.5 ms)
        inc = f0[k0:k1] / FINE_RATE
        phase = ((np.cumsum(inc) - inc + r.random()) % 1.0).astype(np.float32)
        ti = ((phase[:, None] + inc.astype(np.float32)[:, None] * frac[None, :]).reshape(-1)
              * np.float32(TABLE_SIZE)).astype(np.int32) & (TABLE_SIZE - 1)
        voiced = table_a[ti] + upsample_linear(vowel[k0:k1], step, np.float32) * table_diff[ti]
        voiced *= upsample_linear(env[k0:k1], step, np.float32)
        voiced += upsample_linear(burst[k0:k1], step, np.float32) * _noise(r, s1 - s0)
        audio[s0:s1] += np.float32(style.loudness) * voiced
    return pcm16_to_float(float_to_pcm16(audio))


def speech_signals(r: np.random.Generator, track: Track, style: Style, n_frames: int, fps: float,
                   sample_rate: int) -> SpeechSignals:
    """Frame-rate speech signals and 16-bit-grid audio of ``n_frames / fps`` seconds."""
    per_frame = int(round(FINE_RATE / fps))
    n_fine = n_frames * per_frame
    env, f0, vowel, burst = _fine_signals(track, style, n_fine)
    hop = int(round(sample_rate / fps))
    audio = _synthesise(r, style, env, f0, vowel, burst, track.phrases, n_frames * hop, sample_rate)
    env_frame = block_mean(env, per_frame)
    voiced = env > 0
    pitch = block_mean(np.where(voiced, f0 / style.f0_base - 1.0, 0.0), per_frame)
    vowel_frame = block_mean(vowel * env, per_frame) / np.maximum(env_frame, 1e-9)
    return SpeechSignals(speaking=segments_mask(track.phrases, n_frames, fps), envelope=env_frame,
                         vowel=np.where(env_frame > 0, vowel_frame, 0.0), pitch=pitch, audio=audio)
