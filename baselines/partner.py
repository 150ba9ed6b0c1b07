"""Partner-copy baselines: the agent does what the partner (user) does, causally.

- ``mime``: the partner's motion of the current turn, frame for frame (zero lag).
- ``lagged-mirror``: the partner's motion delayed by ``LAG_SECONDS`` = 0.48 s (12 frames at 25 fps),
  the order of human facial mimicry delays and the expression-mirroring lag of the embedded corpus
  (:mod:`dyadbench.synth.corpus`); ``ModelOptions.extra["lag_seconds"]`` overrides it. The model keeps a
  delay line of the last partner frames it has been shown in earlier turns of the stream (its own memory,
  not protocol history, so its output does not depend on the context length n); before the first partner
  frame it holds that first frame.

Both need a partner: single-participant (gaze–head) sessions are refused with an InputError. Both
implement the streaming and the offline interface with identical outputs.
"""

from __future__ import annotations

import numpy as np

from dyadbench.errors import InputError
from dyadbench.protocol.interface import (ModelInfo, ModelOptions, OfflineModel, StreamContext, StreamingModel,
                                          TurnInput)

LAG_SECONDS = 0.48


def _require_partner(name: str, user_motion: np.ndarray, where: str) -> None:
    if user_motion.shape[1] == 0:
        raise InputError(where, f"{name} copies the partner's motion; this session has no partner")


class Mime(StreamingModel, OfflineModel):
    """Copy the partner's current motion."""

    def __init__(self, info: ModelInfo):
        self.info = info
        self._where = "stream"

    def start_stream(self, ctx: StreamContext) -> None:
        self._where = f"{ctx.clip_id}_{ctx.agent}"

    def predict_turn(self, turn: TurnInput) -> np.ndarray:
        _require_partner(self.info.name, turn.user_motion, self._where)
        return np.array(turn.current_user_motion, dtype=np.float32)

    def predict_clip(self, ctx: StreamContext, user_motion: np.ndarray, user_audio: np.ndarray,
                     agent_audio: np.ndarray) -> np.ndarray:
        _require_partner(self.info.name, user_motion, f"{ctx.clip_id}_{ctx.agent}")
        return np.array(user_motion, dtype=np.float32)


class LaggedMirror(StreamingModel, OfflineModel):
    """The partner's motion delayed by a fixed lag (a causal delay line)."""

    def __init__(self, info: ModelInfo, lag_seconds: float = LAG_SECONDS):
        self.info = info
        self.lag_seconds = lag_seconds
        self._lag = 0
        self._line: np.ndarray | None = None
        self._where = "stream"

    def _lag_frames(self, ctx: StreamContext) -> int:
        return int(round(self.lag_seconds * ctx.fps))

    def start_stream(self, ctx: StreamContext) -> None:
        self._lag = self._lag_frames(ctx)
        self._line = None
        self._where = f"{ctx.clip_id}_{ctx.agent}"

    def predict_turn(self, turn: TurnInput) -> np.ndarray:
        _require_partner(self.info.name, turn.user_motion, self._where)
        current = np.asarray(turn.current_user_motion, dtype=np.float32)
        if self._line is None:
            self._line = np.repeat(current[:1], self._lag, axis=0)
        sequence = np.concatenate([self._line, current], axis=0)
        self._line = sequence[sequence.shape[0] - self._lag:]
        return sequence[:turn.frames_per_turn].copy()

    def predict_clip(self, ctx: StreamContext, user_motion: np.ndarray, user_audio: np.ndarray,
                     agent_audio: np.ndarray) -> np.ndarray:
        _require_partner(self.info.name, user_motion, f"{ctx.clip_id}_{ctx.agent}")
        lag = self._lag_frames(ctx)
        motion = np.asarray(user_motion, dtype=np.float32)
        return np.concatenate([np.repeat(motion[:1], lag, axis=0), motion], axis=0)[:motion.shape[0]]


def build_mime(options: ModelOptions) -> Mime:
    return Mime(ModelInfo(name="mime", layout=options.extra.get("layout", "flame56")))


def build_lagged_mirror(options: ModelOptions) -> LaggedMirror:
    lag = float(options.extra.get("lag_seconds", LAG_SECONDS))
    return LaggedMirror(ModelInfo(name="lagged-mirror", layout=options.extra.get("layout", "flame56"),
                                  config={"lag_seconds": lag}), lag)
