"""Trivial baselines that ignore the conversation: zero, mean frame, median frame, random frames.

- ``zero``: every coefficient 0 (the neutral FLAME face, head rotation 0).
- ``mean-frame`` / ``median-frame``: the per-dimension mean / median of every valid frame of every
  participant of the train split, repeated (see :func:`baselines.fitting.frame_statistics`; a layout's
  invalid frames, e.g. Seamless Interaction's zero-filled blocks, are left out).
- ``random``: i.i.d. Gaussian frames with the train mean and covariance,
  x = μ + V·diag(√max(λ, 0))·z, z ~ N(0, I), where Σ = V diag(λ) Vᵀ; the generator of each stream is
  seeded by the stream's seed (derived from the run seed, clip and agent), and frames are drawn in time
  order, so streaming and offline runs give the same frames.

All are history-free: their output never depends on the context length n. They implement both the
streaming and the offline interface.
"""

from __future__ import annotations

import numpy as np

from baselines.fitting import STATS_VERSION, cached_fit, frame_statistics, open_train
from dyadbench.errors import InputError
from dyadbench.motion import LAYOUTS
from dyadbench.protocol.interface import (ModelInfo, ModelOptions, OfflineModel, StreamContext, StreamingModel,
                                          TurnInput)

FIT_VERSION = 1


class ConstantFrame(StreamingModel, OfflineModel):
    """The same frame at every time step."""

    def __init__(self, info: ModelInfo, frame: np.ndarray):
        self.info = info
        self.frame = np.asarray(frame, dtype=np.float32)

    def predict_turn(self, turn: TurnInput) -> np.ndarray:
        return np.tile(self.frame, (turn.frames_per_turn, 1))

    def predict_clip(self, ctx: StreamContext, user_motion: np.ndarray, user_audio: np.ndarray,
                     agent_audio: np.ndarray) -> np.ndarray:
        return np.tile(self.frame, (user_motion.shape[0], 1))


class GaussianFrames(StreamingModel, OfflineModel):
    """I.i.d. frames from N(mean, cov), seeded per stream."""

    def __init__(self, info: ModelInfo, mean: np.ndarray, cov: np.ndarray):
        self.info = info
        self.mean = np.asarray(mean, dtype=np.float64)
        eigval, eigvec = np.linalg.eigh(np.asarray(cov, dtype=np.float64))
        self.factor = eigvec * np.sqrt(np.clip(eigval, 0.0, None))[None, :]
        self._rng = np.random.default_rng(0)

    def start_stream(self, ctx: StreamContext) -> None:
        self._rng = np.random.default_rng(ctx.seed)

    def _draw(self, rng: np.random.Generator, n: int) -> np.ndarray:
        return (self.mean + rng.standard_normal((n, self.mean.shape[0])) @ self.factor.T).astype(np.float32)

    def predict_turn(self, turn: TurnInput) -> np.ndarray:
        return self._draw(self._rng, turn.frames_per_turn)

    def predict_clip(self, ctx: StreamContext, user_motion: np.ndarray, user_audio: np.ndarray,
                     agent_audio: np.ndarray) -> np.ndarray:
        return self._draw(np.random.default_rng(ctx.seed), user_motion.shape[0])


def _info(name: str, options: ModelOptions, **extra) -> ModelInfo:
    return ModelInfo(name=name, layout=options.extra.get("layout", "flame56"), version=str(FIT_VERSION), **extra)


def _fitted(name: str, options: ModelOptions) -> tuple[dict[str, np.ndarray], dict]:
    source = open_train(options.train_split, name)
    stats, digest = cached_fit("frame-stats", STATS_VERSION, source, frame_statistics)
    layout = options.extra.get("layout", "flame56")
    dims, expected = stats["mean"].shape[0], LAYOUTS[layout].dim
    if dims != expected:
        raise InputError(f"{source.dataset}/{source.split}",
                         f"{name}: train motion has {dims} dims, the evaluated layout {layout} has {expected}")
    config = {"train": f"{source.dataset}/{source.split}", "train_frames": int(stats["frames"]),
              "median_stride": int(stats["median_stride"])}
    return stats, {"weights_digest": digest, "config": config}


def build_zero(options: ModelOptions) -> ConstantFrame:
    info = _info("zero", options)
    return ConstantFrame(info, np.zeros(LAYOUTS[info.layout].dim))


def build_mean_frame(options: ModelOptions) -> ConstantFrame:
    stats, extra = _fitted("mean-frame", options)
    return ConstantFrame(_info("mean-frame", options, **extra), stats["mean"])


def build_median_frame(options: ModelOptions) -> ConstantFrame:
    stats, extra = _fitted("median-frame", options)
    return ConstantFrame(_info("median-frame", options, **extra), stats["median"])


def build_random(options: ModelOptions) -> GaussianFrames:
    stats, extra = _fitted("random", options)
    return GaussianFrames(_info("random", options, **extra), stats["mean"], stats["cov"])
