"""Descriptive statistics of one participant's FLAME motion and speech (per clip).

Used by ``dyadbench data info`` to describe a split and by :mod:`dyadbench.synth.calibration` to
compare the synthetic corpus with real DualTalk clips. Every value is a plain per-clip number:

- ``exp_std``: mean over the 50 expression dims of the per-dim std over frames (``_first5``,
  ``_last25``: over those dims only); ``exp_abs_diff``: mean |x_t - x_{t-1}| over dims and frames;
- ``head_std``, ``head_abs_diff``: the same over the 3 head-rotation axes (rad);
- ``jaw_open_mean``, ``jaw_open_std``, ``jaw_open_abs_diff``: jaw axis 0 (rad); ``jaw_side_std``:
  mean std of jaw axes 1-2;
- ``jaw_speech_r`` (only with audio): the best Pearson r over lags 0-``MAX_JAW_LAG`` frames between
  the speech RMS envelope per motion frame and the jaw opening that follows it.
"""

from __future__ import annotations

import numpy as np

from dyadbench.features.logmel import rms_envelope
from dyadbench.motion import EXP, JAW, POSE

MAX_JAW_LAG = 5  # frames searched for the jaw/speech-envelope correlation


def best_lagged_r(driver: np.ndarray, response: np.ndarray, max_lag: int) -> float:
    """max over lags L in [0, max_lag] of Pearson r(driver[t], response[t + L])."""
    n = min(len(driver), len(response))
    best = -1.0
    for lag in range(max_lag + 1):
        x, y = driver[: n - lag], response[lag:n]
        if np.std(x) > 0 and np.std(y) > 0:
            best = max(best, float(np.corrcoef(x, y)[0, 1]))
    return best


def motion_statistics(motion: np.ndarray, audio: np.ndarray | None = None, sample_rate: int = 16_000,
                      fps: float = 25.0) -> dict[str, float]:
    """The ``REAL_CLIPS`` statistics of one participant; ``jaw_speech_r`` only when audio is given."""
    m = np.asarray(motion, dtype=np.float64)
    exp, jaw, head = m[:, EXP], m[:, JAW], m[:, POSE]
    exp_std = exp.std(axis=0)
    stats = {
        "exp_std": float(exp_std.mean()),
        "exp_std_first5": float(exp_std[:5].mean()),
        "exp_std_last25": float(exp_std[-25:].mean()),
        "exp_abs_diff": float(np.abs(np.diff(exp, axis=0)).mean()),
        "head_std": float(head.std(axis=0).mean()),
        "head_abs_diff": float(np.abs(np.diff(head, axis=0)).mean()),
        "jaw_open_mean": float(jaw[:, 0].mean()),
        "jaw_open_std": float(jaw[:, 0].std()),
        "jaw_open_abs_diff": float(np.abs(np.diff(jaw[:, 0])).mean()),
        "jaw_side_std": float(jaw[:, 1:].std(axis=0).mean()),
    }
    if audio is not None:
        stats["jaw_speech_r"] = best_lagged_r(rms_envelope(audio, sample_rate, fps), jaw[:, 0], MAX_JAW_LAG)
    return stats
