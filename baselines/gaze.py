"""Two reference rows for the gaze–head suite (layout ``gaze7``: 7 angles in degrees at 25 fps).

- ``gaze-static``: gaze straight ahead and the head still. ``rest="zero"`` (default) holds all seven
  angles at 0° (head facing forward, eyes centred; needs no data); ``rest="train-mean"`` holds the head
  at the train split's mean head pose (pitch, yaw, roll) with the eyes still centred. Its eyes never move,
  so it has no motion beats (BAS NaN), FixRatio 1 and CompScore 0.
- ``gaze-headcopy``: the head is the ground truth (an ORACLE row, never ranked: it reads the agent's
  ground-truth head through the protocol) and the eyes look where the head points. With the layout's
  eye-in-head angles (``eye_convention="eye-in-head"``, default) that means the eye channels are 0; with
  ``"gaze-in-space"`` (data whose eye channels are gaze directions in space) the eye pitch/yaw copy the
  head pitch/yaw. It is the best a head-only model can do on the gaze patterns when its eyes simply
  follow the head.

Options come from ``ModelOptions.extra`` (``rest``, ``eye_convention``) and are recorded in ``ModelInfo.config``.
Both are deterministic and history-free.
"""

from __future__ import annotations

import numpy as np

from baselines.fitting import cached_fit, frame_statistics, open_train
from baselines.trivial import ConstantFrame
from dyadbench.errors import ConfigError, InputError
from dyadbench.motion import GAZE7
from dyadbench.protocol.interface import ModelInfo, ModelOptions, StreamingModel, TurnInput

VERSION = 1
RESTS = ("zero", "train-mean")
EYE_CONVENTIONS = ("eye-in-head", "gaze-in-space")
HEAD, HEAD_PITCH_YAW, LEFT_EYE, RIGHT_EYE = slice(0, 3), slice(0, 2), slice(3, 5), slice(5, 7)


def _option(options: ModelOptions, key: str, default: str, allowed: tuple[str, ...]) -> str:
    value = options.extra.get(key, default)
    if value not in allowed:
        raise ConfigError(f"{key} must be one of {', '.join(allowed)}, got {value!r}")
    return value


def build_static(options: ModelOptions) -> ConstantFrame:
    """Gaze straight ahead, head still at 0° (``rest="zero"``) or at the train mean head pose."""
    rest = _option(options, "rest", "zero", RESTS)
    frame = np.zeros(GAZE7.dim)
    config: dict = {"rest": rest}
    digest = None
    if rest == "train-mean":
        source = open_train(options.train_split, "gaze-static")
        stats, digest = cached_fit("frame-stats", VERSION, source, frame_statistics)
        if stats["mean"].shape[0] != GAZE7.dim:
            raise InputError(f"{source.dataset}/{source.split}",
                             f"gaze-static: train motion has {stats['mean'].shape[0]} dims, gaze7 has {GAZE7.dim}")
        frame[HEAD] = stats["mean"][HEAD]
        config.update(train=f"{source.dataset}/{source.split}", head_deg=frame[HEAD].round(4).tolist())
    info = ModelInfo(name="gaze-static", layout=GAZE7.name, version=str(VERSION), weights_digest=digest,
                     config=config)
    return ConstantFrame(info, frame)


class HeadCopy(StreamingModel):
    """ORACLE head; eyes along the head direction (see the module docstring)."""

    def __init__(self, info: ModelInfo, eye_convention: str):
        self.info = info
        self.eye_convention = eye_convention

    def predict_turn(self, turn: TurnInput) -> np.ndarray:
        if turn.agent_motion_oracle is None:
            raise RuntimeError("gaze-headcopy reads the ground-truth head: the protocol must hand it the agent's "
                               "motion (ModelInfo.oracle = True)")
        head = np.asarray(turn.agent_motion_oracle[-turn.frames_per_turn:], dtype=np.float32)[:, HEAD]
        out = np.zeros((len(head), GAZE7.dim), dtype=np.float32)
        out[:, HEAD] = head
        if self.eye_convention == "gaze-in-space":
            out[:, LEFT_EYE] = head[:, HEAD_PITCH_YAW]
            out[:, RIGHT_EYE] = head[:, HEAD_PITCH_YAW]
        return out


def build_headcopy(options: ModelOptions) -> HeadCopy:
    """Ground-truth head with the eyes following it (an oracle reference row)."""
    convention = _option(options, "eye_convention", "eye-in-head", EYE_CONVENTIONS)
    info = ModelInfo(name="gaze-headcopy", layout=GAZE7.name, version=str(VERSION), oracle=True,
                     config={"head": "ground truth", "eye_convention": convention})
    return HeadCopy(info, convention)
