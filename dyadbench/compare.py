"""Paired comparison of two runs on the same items: which differences are larger than their uncertainty.

For every metric column both runs score per item, over the N shared items (predictions), with
d_i = b_i − a_i (run B minus run A; items where either value is NaN left out of that column):

- ``diff``: the mean of d_i, with the cluster-robust standard error and the cluster-bootstrap CI over
  dialogues of :class:`dyadbench.uncertainty.Bootstrap` (both directions of a dialogue resampled
  together);
- ``p_value``: two-sided paired t-test on the dialogue level, t = diff / se with C − 1 degrees of freedom
  (C dialogues); 0 when se = 0 and diff ≠ 0;
- ``significant``: the CI excludes 0; ``better``: "A" or "B" by the column's direction when significant,
  "=" when not, "" for descriptive columns without a direction.

With few dialogues (< :data:`MIN_DIALOGUES`) the percentile CI undercovers; the result says so in ``notes``.

The per-item columns are compared: for a pooled column (e.g. L2L's L2, gaze FixRatio) that is the mean
of the per-item values, not the pooled figure.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
from scipy import stats

from dyadbench.errors import InputError
from dyadbench.metrics.columns import declared
from dyadbench.results import load_result
from dyadbench.uncertainty import LEVEL, RESAMPLES, Bootstrap, dialogue_of

RESULT_NAMES = ("result.json", "results.json")  # eval --out and score --out; older score --out
MIN_DIALOGUES = 20
FEW_DIALOGUES = (f"fewer than {MIN_DIALOGUES} dialogues: the percentile bootstrap CI is too narrow (it can exclude 0 "
                 f"where the t-test's p is large); read significance with care")
COLUMNS = ("metric", "higher_is_better", "items", "mean_a", "mean_b", "diff", "se", "ci_low", "ci_high",
           "p_value", "significant", "better")


@dataclass(frozen=True)
class Run:
    """One run's per-item metrics: where they came from, the suite and the scored items' rows."""

    source: Path
    suite: str
    metrics: tuple[str, ...]  # the run's metric columns (the mean metrics it reports)
    rows: list[dict]


def load_run(path: str | Path) -> Run:
    """A result file read by :func:`dyadbench.results.load_result` (``eval``'s or ``score``'s result.json,
    or an older ``score`` results.json with its per_clip.csv beside it), or an output folder holding one;
    InputError naming the file when it is unreadable or holds no per-item values."""
    path = Path(path)
    if path.is_dir():
        found = [path / name for name in RESULT_NAMES if (path / name).is_file()]
        if not found:
            raise InputError(path, f"no {' or '.join(RESULT_NAMES)} in this folder")
        path = found[0]
    result = load_result(path)
    if not result.per_clip:
        raise InputError(path, "has no per-clip metrics (written with --no-per-clip, or an older score "
                               "results.json whose per_clip.csv is gone?); compare needs them")
    return Run(path, result.suite, tuple(result.metrics), result.per_clip)


def higher_is_better(suite: str, key: str) -> bool | None:
    """A column's direction as its suite declares it (:mod:`dyadbench.metrics.columns`; None: descriptive,
    undeclared, or a suite dyadbench does not know)."""
    columns = declared(suite)
    return None if columns is None else columns.higher_is_better(key)


def compare(a: Run, b: Run, *, seed: int = 0, resamples: int = RESAMPLES, level: float = LEVEL) -> dict:
    """The paired comparison B − A (module docstring) as a JSON-ready dict; InputError naming the files
    for different suites or item sets."""
    if a.suite != b.suite:
        raise InputError(b.source, f"suite {b.suite!r} differs from {a.source}'s {a.suite!r}")
    rows_a, rows_b = ({str(r["clip"]): r for r in run.rows} for run in (a, b))
    only_a, only_b = sorted(set(rows_a) - set(rows_b)), sorted(set(rows_b) - set(rows_a))
    if only_a or only_b:
        shown = "; ".join(f"{len(only)} only in {run.source} (e.g. {', '.join(only[:3])})"
                          for only, run in ((only_a, a), (only_b, b)) if only)
        raise InputError(b.source, f"not scored on the same items as {a.source}: {shown}")
    clips = sorted(rows_a)
    keys = [k for k in a.metrics if k in b.metrics and all(k in rows_a[c] and k in rows_b[c] for c in clips)]
    plan = Bootstrap.of([dialogue_of(a.suite, c) for c in clips], seed=seed, resamples=resamples, level=level)
    columns = []
    for key in keys:
        va, vb = (np.array([rows[c][key] for c in clips], dtype=np.float64) for rows in (rows_a, rows_b))
        columns.append(_column(key, higher_is_better(a.suite, key), va, vb, plan))
    notes = [FEW_DIALOGUES] if len(plan.names) < MIN_DIALOGUES else []
    return {"a": str(a.source), "b": str(b.source), "suite": a.suite, "items": len(clips),
            "difference": "B - A", "uncertainty_method": plan.method(), "notes": notes, "columns": columns}


def _column(key: str, higher: bool | None, va: np.ndarray, vb: np.ndarray, plan: Bootstrap) -> dict:
    both = np.isfinite(va) & np.isfinite(vb)
    d = np.where(both, vb - va, np.nan)
    spread = plan.mean(d)
    diff = float(d[both].mean()) if both.any() else math.nan
    significant = bool(spread["ci_low"] > 0 or spread["ci_high"] < 0)
    if higher is None:
        better = ""
    elif not significant:
        better = "="
    else:
        better = "B" if (diff > 0) == higher else "A"
    return {"metric": key, "higher_is_better": higher, "items": int(both.sum()),
            "mean_a": float(va[both].mean()) if both.any() else math.nan,
            "mean_b": float(vb[both].mean()) if both.any() else math.nan,
            "diff": diff, **spread, "p_value": _p_value(diff, spread["se"], plan, both),
            "significant": significant, "better": better}


def _p_value(diff: float, se: float, plan: Bootstrap, defined: np.ndarray) -> float:
    """Two-sided t-test of diff = 0 with the cluster-robust s.e. and C − 1 degrees of freedom."""
    clusters = len(np.unique(plan.clusters[defined]))
    if clusters < 2 or not math.isfinite(diff) or not math.isfinite(se):
        return math.nan
    if se == 0.0:
        return 1.0 if diff == 0.0 else 0.0
    return float(2.0 * stats.t.sf(abs(diff / se), clusters - 1))


def frame(comparison: dict) -> pd.DataFrame:
    """The comparison's columns as a table (:data:`COLUMNS`)."""
    return pd.DataFrame(comparison["columns"], columns=list(COLUMNS))


def text_table(comparison: dict) -> str:
    """A readable table: per column mean A, mean B, B − A ± s.e., the CI, p and the verdict."""
    level = comparison["uncertainty_method"]["level"]
    lines = [f"B - A: B = {comparison['b']}, A = {comparison['a']} ({comparison['suite']}, "
             f"{comparison['items']} items, {comparison['uncertainty_method']['clusters']} dialogues)",
             f"{'metric':<24} {'A':>11} {'B':>11} {'B-A':>11} {'s.e.':>9} {f'{level:.0%} CI':>24} "
             f"{'p':>7}  better"]
    for c in comparison["columns"]:
        ci = f"[{c['ci_low']:.4g}, {c['ci_high']:.4g}]"
        mark = "*" if c["significant"] else " "
        lines.append(f"{c['metric']:<24} {c['mean_a']:>11.4g} {c['mean_b']:>11.4g} {c['diff']:>+11.4g} "
                     f"{c['se']:>9.2g} {ci:>24} {c['p_value']:>7.3g} {mark}{c['better']}")
    lines.append("* the CI excludes 0; better: by the column's direction (blank: no direction)")
    lines += [f"note: {note}" for note in comparison["notes"]]
    return "\n".join(lines)
