"""Speech frontends of TIMAR: per-turn features aligned to motion frames, computed chunk by chunk.

Each 1-s chunk of audio is featurised on its own (no information crosses a turn boundary), giving
``frames_per_turn`` rows per chunk:

- ``logmel`` (embedded default, no download): :func:`dyadbench.features.logmel.logmel_frames`, 40 bands.
- ``wav2vec``: the frozen wav2vec 2.0 frontend of :mod:`dyadbench.features.wav2vec` (1024-d), used
  when its weights are available locally (a clear error otherwise; nothing is downloaded).

The trainable Linear(speech_dim → d_t) that follows lives in the model.
"""

from __future__ import annotations

import numpy as np

from dyadbench.errors import ConfigError, InputError
from dyadbench.features.logmel import logmel_frames
from models.timar.config import SPEECH_DIMS, TimarConfig


class SpeechFrontend:
    """Features (turns·F, dim) float32 of ``turns`` whole chunks of ``samples_per_turn`` samples."""

    name: str
    dim: int

    def __init__(self, cfg: TimarConfig, sample_rate: int = 16_000, fps: float = 25.0):
        self.samples_per_turn, self.frames_per_turn = cfg.samples_per_turn, cfg.frames_per_turn
        self.sample_rate, self.fps = sample_rate, fps
        self.dim = SPEECH_DIMS[self.name]

    def chunk_features(self, chunk: np.ndarray) -> np.ndarray:
        raise NotImplementedError

    def features(self, audio: np.ndarray, turns: int, stats: tuple[float, float] | None = None) -> np.ndarray:
        """Each chunk featurised on its own (subclasses may featurise the whole audio at once).

        ``stats``: (mean, var) of the whole clip's waveform for frontends that normalise the waveform
        (the protocol's ``--speech-norm clip``); log-mel features do not normalise it and ignore them."""
        audio = np.asarray(audio, dtype=np.float32)
        if audio.ndim != 1 or audio.shape[0] < turns * self.samples_per_turn:
            raise InputError("speech", f"need mono audio of at least {turns} x {self.samples_per_turn} samples, "
                                       f"got shape {audio.shape}")
        rows = [self.chunk_features(audio[i * self.samples_per_turn:(i + 1) * self.samples_per_turn])
                for i in range(turns)]
        return np.concatenate(rows, axis=0) if rows else np.zeros((0, self.dim), np.float32)


class LogMelFrontend(SpeechFrontend):
    name = "logmel"

    def chunk_features(self, chunk: np.ndarray) -> np.ndarray:
        """Log-mel rows of one chunk. At a frame rate whose hop is not a whole number of samples (30 fps at
        16 kHz: 533.3) the hop is rounded down (533 samples: frame centres within 0.6 ms of the motion
        frames' over a 1-s turn) and the first ``frames_per_turn`` rows are kept."""
        hop = self.sample_rate / self.fps
        if hop == int(hop):
            return logmel_frames(chunk, self.sample_rate, self.fps, n_mels=self.dim)
        rows = logmel_frames(chunk, self.sample_rate, self.sample_rate / int(hop), n_mels=self.dim)
        return rows[:len(chunk) * self.frames_per_turn // self.samples_per_turn]


class Wav2VecFrontend(SpeechFrontend):
    """:func:`dyadbench.features.wav2vec.wav2vec_frames` (1-s chunks, CNN features interpolated to 25 frames).

    The waveform is normalised before the chunks are cut: with ``stats`` = (mean, var) when given (the whole
    clip's: the release, in training and under ``--speech-norm clip``), otherwise each turn with its own
    statistics (``--speech-norm window``), so a turn's features depend only on that turn's audio: causal,
    and the same whether a stream caches turns or re-encodes its window.
    """

    name = "wav2vec"

    def __init__(self, cfg: TimarConfig, sample_rate: int = 16_000, fps: float = 25.0, weights: str | None = None):
        super().__init__(cfg, sample_rate, fps)
        from dyadbench.features import wav2vec  # noqa: PLC0415  (imports transformers lazily)

        self._wav2vec = wav2vec
        self._model = wav2vec.load_wav2vec(weights or wav2vec.DEFAULT_MODEL)
        self.dim = int(self._model.config.hidden_size)

    def chunk_features(self, chunk: np.ndarray) -> np.ndarray:
        return self._wav2vec.wav2vec_frames(self._model, chunk, self.sample_rate, self.fps)

    def features(self, audio: np.ndarray, turns: int, stats: tuple[float, float] | None = None) -> np.ndarray:
        if stats is None:
            return super().features(audio, turns)
        audio = np.asarray(audio, dtype=np.float32)[:turns * self.samples_per_turn]
        return self._wav2vec.wav2vec_frames(self._model, audio, self.sample_rate, self.fps, stats=stats)


def make_frontend(cfg: TimarConfig, sample_rate: int = 16_000, fps: float = 25.0,
                  wav2vec_weights: str | None = None) -> SpeechFrontend:
    if cfg.speech_frontend == "logmel":
        return LogMelFrontend(cfg, sample_rate, fps)
    frontend = Wav2VecFrontend(cfg, sample_rate, fps, wav2vec_weights)
    if frontend.dim != cfg.speech_dim:
        raise ConfigError(f"the wav2vec 2.0 model at {wav2vec_weights} gives {frontend.dim}-d features; the {cfg.name} "
                          f"config expects {cfg.speech_dim}-d (facebook/wav2vec2-large-960h-lv60-self)")
    return frontend
