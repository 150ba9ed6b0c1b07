"""The result of scoring one set of predictions with one metric suite, and how it is written.

Every suite's ``score_paths(...)`` returns a :class:`ScoreReport`; ``dyadbench score`` prints its table
and writes it as a typed result (``result.json``, :func:`dyadbench.results.external_result`) and
``per_clip.csv``, atomically. Raw values are always kept beside the
publication-scaled ones.
"""

from __future__ import annotations

import io
import math
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from dyadbench import __version__
from dyadbench import atomic
from dyadbench.metrics.columns import ColumnSpec, declared


@dataclass(frozen=True)
class ScoreItem:
    """One predicted agent, in memory: what every suite's ``score_arrays(items, ...)`` consumes.

    ``stem`` is the prediction's name (``<clip>_<agent>``); ``pred`` and ``gt`` (T, D) are in the
    suite's layout; ``partner`` is the partner's ground truth (None for single-participant sessions);
    ``audio`` the agent's own speech (gaze suite: BAS); ``identity`` a speaker/style id when known.
    Arrays of different lengths are truncated to the shortest by the suite (and counted).
    ``pred_source`` / ``gt_source`` name the files the arrays were read from, for messages (default:
    ``prediction <stem>`` / ``ground truth of <stem>``).
    """

    stem: str
    pred: np.ndarray
    gt: np.ndarray
    partner: np.ndarray | None = None
    audio: np.ndarray | None = None
    identity: str | None = None
    fps: float = 25.0
    sample_rate: int = 16_000
    pred_source: str | None = None
    gt_source: str | None = None

    @property
    def pred_name(self) -> str:
        return self.pred_source or f"prediction {self.stem}"

    @property
    def gt_name(self) -> str:
        return self.gt_source or f"ground truth of {self.stem}"


@dataclass
class ScoreReport:
    """Scores of one suite over one set of predictions.

    - ``metrics``: raw mean over scored items, keyed by metric name.
    - ``scaled`` / ``scaling``: the same keys times their publication scale, and the scale, both from the
      suite's one declaration (:func:`dyadbench.metrics.columns.declared`; scale 1 for undeclared keys).
    - ``per_item``: one dict per scored item; first key ``clip`` (the prediction's stem / id).
    - ``excluded``: ``{"clip": ..., "reason": ...}`` for predictions present but not scored.
    - ``coverage``: ``{"expected": n, "scored": n, "missing": [...], "extra": [...]}`` vs ground truth;
      ``not_computable``: ``{"clip", "metrics", "reason"}`` for scored items whose listed metrics could
      not be computed (e.g. no partner ground truth), when the suite reports any.
    - ``uncertainty`` / ``uncertainty_method``: each column's standard error and bootstrap CI over
      dialogues, computed when scoring (:func:`dyadbench.uncertainty.estimate`), and how.
    """

    suite: str
    metrics: dict[str, float]
    per_item: list[dict]
    excluded: list[dict] = field(default_factory=list)
    coverage: dict = field(default_factory=dict)
    config: dict = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    columns: list[ColumnSpec] = field(default_factory=list)  # printed table order (paper order)
    uncertainty: dict = field(default_factory=dict)  # metric -> se, ci_low, ci_high (dyadbench.uncertainty)
    uncertainty_method: dict = field(default_factory=dict)  # method, resamples, level, seed, clusters
    dyadbench_version: str = __version__

    @property
    def scaled(self) -> dict[str, float]:
        columns = declared(self.suite)
        return dict(self.metrics) if columns is None else columns.scaled(self.metrics)

    @property
    def scaling(self) -> dict[str, float]:
        columns = declared(self.suite)
        return {k: 1.0 for k in self.metrics} if columns is None else columns.scaling(self.metrics)

    @property
    def n_scored(self) -> int:
        return len(self.per_item)

    @property
    def complete(self) -> bool:
        """True when every expected item was scored (nothing missing, nothing excluded)."""
        return not self.excluded and not self.coverage.get("missing")

    def coverage_line(self) -> str:
        expected = self.coverage.get("expected", self.n_scored)
        line = f"scored {self.n_scored} of {expected}"
        missing = self.coverage.get("missing") or []
        if missing:
            shown = ", ".join(missing[:5]) + (f", … ({len(missing) - 5} more)" if len(missing) > 5 else "")
            line += f"; missing: {shown}"
        if self.excluded:
            line += f"; excluded {len(self.excluded)}: " + ", ".join(
                f"{e['clip']} ({e['reason']})" for e in self.excluded[:5])
        not_computable = self.coverage.get("not_computable") or []
        if not_computable:
            names = dict.fromkeys(k.rsplit("_", 1)[0] for e in not_computable for k in e["metrics"])
            line += (f"; {len(not_computable)} of them without {', '.join(names)} (not computable, "
                     f"see coverage.not_computable)")
        extra = self.coverage.get("extra") or []
        if extra:
            line += f"; {len(extra)} predictions without ground truth ignored"
        return line

    def table(self, width: int = 100) -> str:
        """Readable table of scaled values in the column order of the suite's paper.

        Wide tables are wrapped into blocks of at most ``width`` characters (header line + value line).
        """
        cols = self.columns or [ColumnSpec(k, k, None) for k in self.metrics]
        headers = [c.text_header for c in cols]
        values = [_fmt(self.scaled.get(c.key, math.nan)) for c in cols]
        widths = [max(len(h), len(v)) for h, v in zip(headers, values)]
        blocks, start = [], 0
        while start < len(cols):
            end, used = start + 1, widths[start]
            while end < len(cols) and used + 2 + widths[end] <= width:
                used += 2 + widths[end]
                end += 1
            span = range(start, end)
            head = "  ".join(headers[i].rjust(widths[i]) for i in span)
            row = "  ".join(values[i].rjust(widths[i]) for i in span)
            blocks.append(f"{head}\n{row}")
            start = end
        return "\n\n".join(blocks)

    def to_dict(self) -> dict:
        d = asdict(self)
        d.pop("columns")
        d.pop("per_item")
        d = {"suite": d.pop("suite"), "metrics": d.pop("metrics"), "scaled": self.scaled, **d}
        d["n_scored"] = self.n_scored
        d["scaling"] = self.scaling
        return d

    def per_item_frame(self) -> pd.DataFrame:
        return pd.DataFrame(self.per_item)

    def write_per_item(self, path: str | Path) -> Path:
        """Write the per-item metrics as CSV (``per_clip.csv``), atomically."""
        buf = io.StringIO()
        self.per_item_frame().to_csv(buf, index=False, float_format="%.10g")
        return atomic.write_text(path, buf.getvalue())


def _fmt(value: float) -> str:
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return "nan"
    return f"{value:.4g}" if abs(value) < 1e4 else f"{value:.4e}"
