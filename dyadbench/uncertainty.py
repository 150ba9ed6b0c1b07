"""Uncertainty of every figure: standard errors and seeded cluster-bootstrap confidence intervals.

The two directions of a dialogue (each participant as the agent) are not independent, so every
estimate treats a *dialogue* as the unit: :func:`dialogue_of` maps an item's stem to its dialogue, and
the bootstrap draws dialogues with replacement, keeping all of a drawn dialogue's items together.

A column that is the mean over items of per-item values y_i (items whose value is NaN left out, as the
suites aggregate) gets

- the cluster-robust standard error of the mean over C dialogues with sums S_c = Σ_{i∈c} y_i and
  counts n_c (N = Σ n_c items, m = Σ S_c / N):
  :math:`\\mathrm{se}^2 = \\frac{C}{C-1}\\sum_c (S_c - n_c m)^2 / N^2`
  (with one item per dialogue this is the usual s/√N, s the sample s.d. with ddof = 1);
- a percentile bootstrap CI: B resamples of C dialogues drawn with replacement (numpy Generator seeded
  by ``derive_seed(seed, "cluster-bootstrap", C)``); replicate b's mean is
  :math:`m_b = \\sum_c w_{bc} S_c / \\sum_c w_{bc} n_c` (w_bc = times dialogue c was drawn), and the CI
  is the (1 − level)/2 and (1 + level)/2 quantiles of the m_b (``numpy.quantile``, linear).

A set-level column (a statistic of the whole set, e.g. a ratio of pooled frame counts) is recomputed on
every replicate by a function of the item weights w_bi (how often item i's dialogue was drawn): its CI
is the same quantiles and its ``se`` the s.d. (ddof = 1) of the replicates. A column where recomputing
is not cheap is recorded as ``{"unavailable": reason}``.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from typing import Callable, Mapping

import numpy as np

from dyadbench.datasets.gaze import PARTICIPANT as GAZE_PARTICIPANT
from dyadbench.seeding import derive_seed

METHOD = "cluster bootstrap over dialogues"
RESAMPLES = 1000
LEVEL = 0.95
SE_RULE = ("means of per-item values: cluster-robust s.e. sqrt(C/(C-1) * sum_c (S_c - n_c*m)^2) / N; "
           "set-level statistics: s.d. (ddof=1) of the bootstrap replicates")

#: A set-level statistic recomputed from item weights: (B, N) weights -> (B,) values.
SetStatistic = Callable[[np.ndarray], np.ndarray]

_SEGMENT = re.compile(r"-f\d+$")


def dialogue_of(suite: str, stem: str) -> str:
    """The dialogue an item belongs to (the unit the bootstrap resamples), from its stem.

    - react: the sample's speaker path ``<dataset>/<session>/<role>/<index>``: the session
      (``<dataset>/<session>``; every segment and both roles of a session are one conversation);
    - gaze: the session (``<session>`` or its ``<session>-f<frame>`` segments, with or without the
      ``_subject`` suffix eval adds);
    - l2l: the window (``<host>_<split>_<n>``; one listener per window);
    - dualtalk and others: the clip, i.e. the stem without its ``_<agent>`` suffix.
    """
    if suite == "react":
        return "/".join(stem.split("/")[:2])
    if suite == "gaze":
        return _SEGMENT.sub("", stem.removesuffix(f"_{GAZE_PARTICIPANT}"))
    return stem.rsplit("_", 1)[0] if "_" in stem else stem


@dataclass(frozen=True)
class Bootstrap:
    """The resampling plan of one set of items: dialogues, and B draws of them with replacement."""

    clusters: np.ndarray  # (N,) dialogue index of every item (dialogues sorted by name)
    names: tuple[str, ...]  # dialogue names
    draws: np.ndarray  # (B, C) times each dialogue was drawn in each replicate
    seed: int
    level: float

    @classmethod
    def of(cls, dialogues: list[str], *, seed: int, resamples: int = RESAMPLES, level: float = LEVEL) -> "Bootstrap":
        names = tuple(sorted(set(dialogues)))
        index = {name: c for c, name in enumerate(names)}
        clusters = np.array([index[d] for d in dialogues], dtype=np.int64)
        rng = np.random.default_rng(derive_seed(seed, "cluster-bootstrap", len(names)))
        picks = rng.integers(0, len(names), size=(resamples, len(names)))
        draws = np.zeros((resamples, len(names)), dtype=np.float64)
        np.add.at(draws, (np.arange(resamples)[:, None], picks), 1.0)
        return cls(clusters, names, draws, seed, level)

    @property
    def item_weights(self) -> np.ndarray:
        """(B, N): how often each item's dialogue was drawn in each replicate."""
        return self.draws[:, self.clusters]

    def method(self) -> dict:
        """The record every result keeps beside its uncertainty."""
        return {"method": METHOD, "resamples": int(self.draws.shape[0]), "level": self.level, "seed": self.seed,
                "clusters": len(self.names), "se": SE_RULE}

    def interval(self, replicates: np.ndarray) -> tuple[float, float]:
        finite = replicates[np.isfinite(replicates)]
        if finite.size == 0:
            return math.nan, math.nan
        tail = (1.0 - self.level) / 2.0
        low, high = np.quantile(finite, [tail, 1.0 - tail])
        return float(low), float(high)

    def mean(self, values: np.ndarray) -> dict:
        """se and CI of the mean of ``values`` (N,) over its finite entries (module docstring)."""
        values = np.asarray(values, dtype=np.float64)
        defined = np.isfinite(values)
        if not defined.any():
            return {"se": math.nan, "ci_low": math.nan, "ci_high": math.nan}
        C = len(self.names)
        sums = np.bincount(self.clusters, weights=np.where(defined, values, 0.0), minlength=C)
        counts = np.bincount(self.clusters, weights=defined.astype(np.float64), minlength=C)
        n = counts.sum()
        m = sums.sum() / n
        occupied = counts > 0
        k = int(occupied.sum())
        se = (math.sqrt(k / (k - 1) * float(np.sum((sums - counts * m)[occupied] ** 2))) / n) if k > 1 else math.nan
        with np.errstate(invalid="ignore", divide="ignore"):
            replicates = (self.draws @ sums) / (self.draws @ counts)
        low, high = self.interval(replicates)
        return {"se": se, "ci_low": low, "ci_high": high}

    def statistic(self, fn: SetStatistic) -> dict:
        """se (s.d. of the replicates) and CI of a set-level statistic recomputed on every replicate."""
        replicates = np.asarray(fn(self.item_weights), dtype=np.float64)
        finite = replicates[np.isfinite(replicates)]
        se = float(np.std(finite, ddof=1)) if finite.size > 1 else math.nan
        low, high = self.interval(replicates)
        return {"se": se, "ci_low": low, "ci_high": high}


def estimate(suite: str, rows: list[dict], mean_keys: list[str], *, seed: int,
             set_level: Mapping[str, SetStatistic] | None = None,
             unavailable: Mapping[str, str] | None = None,
             resamples: int = RESAMPLES, level: float = LEVEL) -> tuple[dict, dict]:
    """``(uncertainty, method)`` of a suite's columns over its scored items ``rows`` (key ``clip``).

    ``mean_keys``: columns that are the mean of the rows' values; ``set_level``: columns recomputed from
    item weights (:data:`SetStatistic`, items in the order of ``rows``); ``unavailable``: column -> why
    no uncertainty is given. Records are in the order mean_keys, set_level, unavailable.
    """
    plan = Bootstrap.of([dialogue_of(suite, row["clip"]) for row in rows], seed=seed, resamples=resamples,
                        level=level)
    out: dict[str, dict] = {}
    for key in mean_keys:
        out[key] = plan.mean(np.array([row.get(key, math.nan) for row in rows], dtype=np.float64))
    for key, fn in (set_level or {}).items():
        out[key] = plan.statistic(fn)
    for key, reason in (unavailable or {}).items():
        out[key] = {"unavailable": reason}
    return out, plan.method()


def ratio(numerator: np.ndarray, denominator: np.ndarray) -> SetStatistic:
    """A pooled ratio Σ w_i a_i / Σ w_i b_i (e.g. fixation frames over all frames) as a set statistic."""
    a, b = np.asarray(numerator, np.float64), np.asarray(denominator, np.float64)
    return lambda w: (w @ a) / (w @ b)
