"""ORACLE — the ground-truth copy. Not a baseline to beat: an upper bound that checks the pipeline.

It returns the agent's own ground-truth motion of the current turn, which the protocol hands only to
models whose ``ModelInfo.oracle`` is True. Its FD, P-FD and MSE are 0 by construction; results carry
``oracle = true`` and leaderboards mark it and never rank it.
"""

from __future__ import annotations

import numpy as np

from dyadbench.protocol.interface import ModelInfo, ModelOptions, StreamingModel, TurnInput


class GroundTruthCopy(StreamingModel):
    """ORACLE: copies the agent's ground truth of the current turn."""

    def __init__(self, info: ModelInfo):
        self.info = info

    def predict_turn(self, turn: TurnInput) -> np.ndarray:
        if turn.agent_motion_oracle is None:
            raise RuntimeError("the protocol did not hand the oracle its ground truth (info.oracle must be True)")
        return np.array(turn.agent_motion_oracle[-turn.frames_per_turn:], dtype=np.float32)


def build_oracle(options: ModelOptions) -> GroundTruthCopy:
    return GroundTruthCopy(ModelInfo(name="oracle", layout=options.extra.get("layout", "flame56"), oracle=True))
