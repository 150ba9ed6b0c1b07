"""DualTalk motion files: ground-truth ``.npz`` and prediction ``.npy``.

Ground truth (one file per participant, ``<clip>_speaker{1,2}.npz``) stores ``exp`` (T, 50) and
``pose`` (T, 6) = [head rotation 3 | jaw 3], plus ``shape``, ``tex``, ``cam``, ``light`` that the
benchmark ignores. Inside dyadbench motion is (T, 56) = [exp 50 | jaw 3 | head rotation 3], so
:func:`load_gt_npz` applies the pose-half swap (:func:`dyadbench.motion.dualtalk_to_flame56`) and
:func:`write_gt_npz` undoes it. Predictions are (T, 56) float arrays in the dyadbench order already.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from dyadbench import atomic
from dyadbench.arrays import check_motion, load_npy, load_npz
from dyadbench.errors import InputError
from dyadbench.motion import FLAME56, dualtalk_to_flame56, flame56_to_dualtalk

GT_KEYS = ("exp", "pose")
EXP_DIM, POSE_DIM = 50, 6


def load_gt_npz(path: str | Path) -> np.ndarray:
    """Read a DualTalk ground-truth ``.npz`` as (T, 56) float64 [exp | jaw | head rotation].

    Raises :class:`InputError` naming the file when it is missing or unreadable, holds pickled
    arrays, lacks ``exp``/``pose``, has wrong shapes, mismatched lengths, a non-float dtype or
    non-finite values.
    """
    path = Path(path)
    arrays = load_npz(path, list(GT_KEYS))
    exp = check_motion(arrays["exp"], f"{path}[exp]", EXP_DIM)
    pose = check_motion(arrays["pose"], f"{path}[pose]", POSE_DIM)
    if exp.shape[0] != pose.shape[0]:
        raise InputError(path, f"exp has {exp.shape[0]} frames but pose has {pose.shape[0]}")
    return dualtalk_to_flame56(exp, pose)


def write_gt_npz(path: str | Path, motion56: np.ndarray, extra: dict[str, np.ndarray] | None = None) -> Path:
    """Write (T, 56) motion as a DualTalk ground-truth ``.npz`` (atomically).

    Stores ``exp`` (T, 50) and ``pose`` (T, 6) = [head rotation | jaw] as float32, plus any ``extra``
    arrays (e.g. ``shape``, ``tex``, ``cam``, ``light``) unchanged.
    """
    motion = check_motion(motion56, "motion to write", FLAME56.dim)
    extra = dict(extra or {})
    clash = sorted(set(extra) & set(GT_KEYS))
    if clash:
        raise InputError(path, f"extra arrays may not be named {', '.join(clash)}")
    exp, pose = flame56_to_dualtalk(motion)
    return atomic.save_npz(path, exp=exp.astype(np.float32), pose=pose.astype(np.float32), **extra)


def load_prediction(path: str | Path, *, finite: bool = True) -> np.ndarray:
    """Read one (T, 56) prediction ``.npy`` [exp | jaw | head rotation] as float64.

    ``finite=False`` returns arrays with NaN/inf unchanged, so a scorer can exclude and list them.
    """
    return check_motion(load_npy(path), path, FLAME56.dim, finite=finite)
