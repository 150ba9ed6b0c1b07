"""Motion layouts: the 56-d FLAME layout of DualTalk/TIMAR predictions and the 7-d gaze–head layout.

FLAME 56 (prediction order, used everywhere inside dyadbench)::

    [ exp (50) | jaw (3) | pose = global head rotation (3) ]

The DualTalk ground-truth ``.npz`` stores ``pose`` (T, 6) = [head rotation (3) | jaw (3)], i.e. the
opposite order; :func:`dualtalk_to_flame56` applies that swap. Learning2Listen stores
[exp 50 | rotation 3 | jaw 3] in its first 56 of 184 dims; :func:`l2l_to_flame56` swaps those too.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

FPS = 25.0
SAMPLE_RATE = 16_000


@dataclass(frozen=True)
class MotionLayout:
    """A named per-frame motion vector with named component slices.

    ``plausible_abs`` bounds the magnitude of any value of real motion in ``units`` with a wide margin;
    a file with larger values is scored with a warning naming it (:mod:`dyadbench.scoring.policy`).
    """

    name: str
    dim: int
    components: dict[str, slice]
    units: str
    plausible_abs: float

    def component(self, motion: np.ndarray, name: str) -> np.ndarray:
        return motion[..., self.components[name]]


FLAME56 = MotionLayout(
    name="flame56",
    dim=56,
    components={"exp": slice(0, 50), "jaw": slice(50, 53), "pose": slice(53, 56)},
    units="FLAME coefficients (exp), axis-angle radians (jaw, pose)",
    # expression coefficients are in units of the FLAME basis' standard deviations (|x| of a few in real
    # and synthetic data); a rotation angle is at most pi radians
    plausible_abs=100.0,
)
EXP, JAW, POSE = (FLAME56.components[c] for c in ("exp", "jaw", "pose"))
FLAME_COMPONENTS = ("exp", "jaw", "pose")

GAZE7 = MotionLayout(
    name="gaze7",
    dim=7,
    components={"head": slice(0, 3), "gaze": slice(3, 7), "all": slice(0, 7)},
    units="degrees: head pitch, yaw, roll; left-eye pitch, yaw; right-eye pitch, yaw",
    plausible_abs=360.0,  # a full turn: no head or eye angle in degrees goes beyond it
)

LAYOUTS = {FLAME56.name: FLAME56, GAZE7.name: GAZE7}


def dualtalk_to_flame56(exp: np.ndarray, pose: np.ndarray) -> np.ndarray:
    """DualTalk npz (exp (T,50), pose (T,6) = [rot | jaw]) -> (T,56) [exp | jaw | rot] float64."""
    return np.concatenate([exp, pose[:, 3:6], pose[:, 0:3]], axis=1).astype(np.float64)


def flame56_to_dualtalk(motion: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Inverse of :func:`dualtalk_to_flame56`: (T,56) -> (exp (T,50), pose (T,6) = [rot | jaw])."""
    exp = motion[:, EXP]
    pose = np.concatenate([motion[:, POSE], motion[:, JAW]], axis=1)
    return exp, pose


def l2l_to_flame56(features: np.ndarray) -> np.ndarray:
    """Learning2Listen (..., 184) -> (..., 56): [exp 0:50 | rot 50:53 | jaw 53:56] -> [exp | jaw | rot]."""
    f = features[..., :56]
    return np.concatenate([f[..., 0:50], f[..., 53:56], f[..., 50:53]], axis=-1)


def flame56_to_l2l(motion: np.ndarray) -> np.ndarray:
    """Inverse of :func:`l2l_to_flame56` on the first 56 dims: [exp | jaw | rot] -> [exp | rot | jaw]."""
    return np.concatenate([motion[..., EXP], motion[..., POSE], motion[..., JAW]], axis=-1)
