"""The corpus calibration: per-clip motion statistics measured on two real DualTalk clips.

``REAL_CLIPS`` holds the statistics of :func:`dyadbench.datasets.statistics.motion_statistics` measured
on two publicly released DualTalk demo clips (23.5 s and 30 s). The synthetic corpus is meant to sit
within a factor of ``TOLERANCE`` of the range those two clips span, per statistic.
"""

from __future__ import annotations

TOLERANCE = 3.0

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
