"""Summaries over training seeds shared by the seeded benchmarks (SFMS Tables III–IV, the StyGazeTalk
seed sweep, the StyGazeTalk style-window comparison).

``mean_se(values)`` = (mean, s / √n), s the sample standard deviation (ddof = 1): the standard error of
the mean over seeds; NaN for a single value (no spread to estimate).
"""

from __future__ import annotations

import math
from typing import Iterable

import numpy as np


def mean_se(values: Iterable[float]) -> tuple[float, float]:
    """Mean and standard error (sample std / √n; NaN for one value) of ``values``."""
    v = np.asarray(list(values), dtype=np.float64)
    return float(v.mean()), float(v.std(ddof=1) / math.sqrt(len(v))) if len(v) > 1 else float("nan")
