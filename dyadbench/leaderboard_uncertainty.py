"""Uncertainty columns of the leaderboards (``dyadbench leaderboard --uncertainty se|ci``).

Each dyadbench row's standard error and CI come from its result file's ``uncertainty`` record
(:mod:`dyadbench.uncertainty`), scaled like the value (printed = raw × scale). Rows of results written
before uncertainty was recorded, published rows and columns without an uncertainty (recorded as
unavailable) get empty cells. The wide CSV gains ``<col>_se`` or ``<col>_ci_low`` / ``<col>_ci_high``
after each column; LaTeX cells print ``value ± se`` or ``value [low, high]``.
"""

from __future__ import annotations

import math
from functools import lru_cache

import pandas as pd

from dyadbench.results import load_result

#: Option value -> the uncertainty fields it adds.
MODES: dict[str, tuple[str, ...]] = {"none": (), "se": ("se",), "ci": ("ci_low", "ci_high")}
FIELDS = ("se", "ci_low", "ci_high")


@lru_cache(maxsize=None)
def _recorded(path: str) -> dict:
    return load_result(path).uncertainty


def with_uncertainty(long: pd.DataFrame) -> pd.DataFrame:
    """``long`` with scaled ``se``, ``ci_low`` and ``ci_high`` columns (NaN where none is recorded)."""
    values = {f: [] for f in FIELDS}
    for source, file, metric, scale in zip(long["source"], long["reference"], long["metric"], long["scale"]):
        record = _recorded(str(file)).get(metric, {}) if source == "dyadbench" else {}
        for f in FIELDS:
            value = record.get(f)
            values[f].append(math.nan if value is None else float(value) * float(scale))
    _recorded.cache_clear()
    return long.assign(**values)


def columns(key: str, mode: str) -> list[str]:
    """The wide table's uncertainty columns of ``key``."""
    return [f"{key}_{f}" for f in MODES[mode]]


def latex_suffix(row: pd.Series, key: str, digits: int) -> str:
    """`` $\\pm$ se`` or `` [low, high]`` after a LaTeX cell, by the uncertainty columns the wide table
    holds; '' without them or without a recorded value."""
    for mode in ("se", "ci"):
        values = [row.get(c) for c in columns(key, mode)]
        if all(c in row.index for c in columns(key, mode)):
            if any(v is None or pd.isna(v) for v in values):
                return ""
            if mode == "se":
                return rf" $\pm$ {values[0]:.{digits}f}"
            return f" [{values[0]:.{digits}f}, {values[1]:.{digits}f}]"
    return ""
