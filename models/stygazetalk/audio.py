"""Window-local speech features for StyGazeTalk (D10–D13).

The features of a window are computed from that window's waveform only (D12): frames u..u+M−1 read the
samples [hop·u, hop·(u+M)), so a generated block never reads audio after its own last frame, and
training and inference see identical features. Log-mel (D13; :mod:`dyadbench.features.logmel`) is the
default; wav2vec 2.0 (:mod:`dyadbench.features.wav2vec`, 1-s chunks inside the window) is used when
the config asks for it and local weights exist (nothing is downloaded).
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from dyadbench.errors import ConfigError
from dyadbench.features.logmel import logmel_frames
from dyadbench.features.wav2vec import load_wav2vec, wav2vec_frames
from dyadbench.motion import FPS, SAMPLE_RATE
from models.stygazetalk.config import GeneratorConfig

HOP = SAMPLE_RATE // int(FPS)  # 640 samples per motion frame


def feature_dim(cfg: GeneratorConfig) -> int:
    if cfg.audio_features == "logmel":
        return cfg.n_mels
    return int(_wav2vec(cfg.wav2vec_path).config.hidden_size)


def window_audio(audio: np.ndarray, start_frame: int, frames: int) -> np.ndarray:
    """Samples of frames [start, start+frames), zero-padded where the audio ends early."""
    lo, hi = start_frame * HOP, (start_frame + frames) * HOP
    chunk = np.asarray(audio[lo:hi], dtype=np.float32)
    if chunk.shape[0] < hi - lo:
        chunk = np.pad(chunk, (0, hi - lo - chunk.shape[0]))
    return chunk


def raw_features(cfg: GeneratorConfig, waveform: np.ndarray) -> np.ndarray:
    """Un-normalised features (len(waveform) // 640, F) float32 of one waveform chunk."""
    if cfg.audio_features == "logmel":
        return logmel_frames(waveform, SAMPLE_RATE, FPS, n_mels=cfg.n_mels, win_length=cfg.logmel_win_length)
    return wav2vec_frames(_wav2vec(cfg.wav2vec_path), waveform, SAMPLE_RATE, FPS)


@lru_cache(maxsize=2)
def _wav2vec(path: str | None):
    """The frozen local wav2vec 2.0 model (D10–D11); a ConfigError naming what is missing otherwise."""
    if path is None:
        raise ConfigError("audio_features='wav2vec' needs wav2vec_path: a local wav2vec2-base-960h folder "
                          "(nothing is downloaded); the default log-mel features need none")
    return load_wav2vec(path)
