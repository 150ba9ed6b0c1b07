"""DualTalk's speech inputs: frame count, waveform normalisation and the log-mel input of the ``tiny`` size.

- Frames: T' = ceil(len(audio1) / 16000 * 25) computed in floating point as the release does
  (4480 samples give 8 frames, not the exact ceiling 7).
- Normalisation (wav2vec 2.0 processor, ``do_normalize``): x' = (x - mean) / sqrt(var + 1e-7), with the
  statistics of the audio given (a streamed window: causal), or given ``(mean, var)`` statistics (the
  whole clip, as the release does offline; under streaming this reads future audio).
- ``logmel`` input: :func:`dyadbench.features.logmel.logmel_frames` of the normalised waveform, cut or
  edge-padded to T' rows.
"""

from __future__ import annotations

import math

import numpy as np

from dyadbench.features.logmel import logmel_frames
from models.dualtalk.config import LOGMEL_BANDS

SAMPLE_RATE = 16_000
FPS = 25.0
NORM_EPS = 1e-7


def frame_count(num_samples: int, sample_rate: int = SAMPLE_RATE, fps: float = FPS) -> int:
    """T' = ceil(num_samples / sample_rate * fps), in floating point (the release's arithmetic)."""
    return math.ceil(num_samples / sample_rate * fps)


def waveform_stats(audio: np.ndarray) -> tuple[float, float]:
    """(mean, variance) of a waveform, in float64."""
    x = np.asarray(audio, dtype=np.float64)
    return float(x.mean()), float(x.var())


def normalise_waveform(audio: np.ndarray, stats: tuple[float, float] | None = None) -> np.ndarray:
    """(x - mean) / sqrt(var + 1e-7) as float32; ``stats`` None: the given audio's own statistics."""
    mean, var = waveform_stats(audio) if stats is None else stats
    return ((np.asarray(audio, dtype=np.float64) - mean) / math.sqrt(var + NORM_EPS)).astype(np.float32)


def logmel_input(normalised: np.ndarray, frames: int, sample_rate: int = SAMPLE_RATE, fps: float = FPS) -> np.ndarray:
    """(frames, 40) log-mel rows of a normalised waveform (last row repeated when the audio is short)."""
    rows = logmel_frames(normalised, sample_rate, fps, n_mels=LOGMEL_BANDS)[:frames]
    if rows.shape[0] < frames:
        fill = rows[-1:] if rows.shape[0] else np.zeros((1, LOGMEL_BANDS), np.float32)
        rows = np.concatenate([rows, np.repeat(fill, frames - rows.shape[0], axis=0)])
    return rows
