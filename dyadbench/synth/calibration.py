"""Per-clip motion statistics, and their values on two real DualTalk clips (the corpus calibration).

:func:`motion_statistics` measures one participant's (T, 56) motion [exp | jaw | head rotation] and
speech; ``REAL_CLIPS`` holds the same statistics measured on two publicly released DualTalk demo clips
(23.5 s and 30 s). The synthetic corpus is meant to sit within a factor of ``TOLERANCE`` of the range
those two clips span, per statistic.
"""

from __future__ import annotations

import numpy as np

from dyadbench.features.logmel import rms_envelope
from dyadbench.motion import EXP, JAW, POSE

TOLERANCE = 3.0
MAX_JAW_LAG = 5  # frames searched for the jaw/speech-envelope correlation

# statistic -> (clip A, clip B) measured on real DualTalk ground truth
REAL_CLIPS = {
    "exp_std": (0.54, 0.40),  # mean over dims of the per-dim std
    "exp_std_first5": (0.74, 0.51),
    "exp_std_last25": (0.50, 0.36),
    "exp_abs_diff": (0.15, 0.087),  # mean |x_t - x_{t-1}|
    "head_std": (0.097, 0.027),  # rad, mean per-axis std
    "head_abs_diff": (0.0089, 0.0033),
    "jaw_open_mean": (0.17, 0.011),
    "jaw_open_std": (0.063, 0.031),
    "jaw_open_abs_diff": (0.020, 0.0052),
    "jaw_side_std": (0.021, 0.011),  # jaw axes 1-2
    "jaw_speech_r": (0.1, 0.41),  # best Pearson r of jaw opening vs own RMS envelope, lags 0-5 frames
}


def calibration_range(name: str, tolerance: float = TOLERANCE) -> tuple[float, float]:
    """[min / tolerance, max * tolerance] of a statistic over the real clips."""
    a, b = REAL_CLIPS[name]
    return min(a, b) / tolerance, max(a, b) * tolerance


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
