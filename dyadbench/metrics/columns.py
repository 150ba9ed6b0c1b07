"""What every metric suite declares about its columns, once: direction, publication scale, order, primary.

Each suite module (``dyadbench.metrics.<suite>``) holds one :class:`SuiteColumns` named ``COLUMNS``;
:func:`declared` finds it by suite name. The same declaration gives

- a scored result's ``scaled`` values and its ``scaling`` (:meth:`SuiteColumns.scaled`,
  :meth:`SuiteColumns.scaling`): printed value = raw × scale, for every key, printed or not;
- the leaderboard's ``scale`` and ``higher_is_better`` per metric, the order of the wide tables'
  columns (the paper's order) and the column that ranks rows (``primary``: ascending when lower is
  better, descending when higher is better);
- the headers of ``dyadbench score``'s table and of the LaTeX tables.

A key without a declaration has scale 1 and no direction, and is not printed in the paper layout.
"""

from __future__ import annotations

import importlib
import math
from dataclasses import dataclass


@dataclass(frozen=True)
class ColumnSpec:
    """One metric key: ``header`` as printed; ``higher_is_better`` None for descriptive columns (a
    variance, a ground-truth reference value: judged against the ground truth, never ordered);
    ``scale`` the publication factor (printed = raw × scale); ``unit`` the printed name of the scale
    (default ``x10`` / ``x1e3``); ``table`` False for keys kept in results and ``long.csv`` only;
    ``reference`` the printed key of which this is the ground truth's own value (e.g. ``var_gt_exp`` for
    ``var_exp``): the wide tables show it in a ground-truth row under that column, never as a column."""

    key: str
    header: str
    higher_is_better: bool | None
    scale: float = 1.0
    unit: str | None = None
    table: bool = True
    reference: str | None = None

    def scale_label(self) -> str:
        """How the scale is printed: ``unit`` if given, else ``x10^k`` as ``x10`` / ``x1e3``; '' for 1."""
        if self.unit is not None:
            return self.unit
        if self.scale == 1.0:
            return ""
        exponent = round(math.log10(self.scale))
        return "x10" if exponent == 1 else f"x1e{exponent}"

    @property
    def text_header(self) -> str:
        """The header with its scale as ``dyadbench score`` prints it, e.g. ``FD jaw x1e3``."""
        label = self.scale_label()
        return f"{self.header} {label}" if label else self.header


@dataclass(frozen=True)
class SuiteColumns:
    """Every declared key of one suite in the paper's order (printed columns first) and the primary key."""

    suite: str
    columns: tuple[ColumnSpec, ...]
    primary: str

    def __post_init__(self) -> None:
        keys = [c.key for c in self.columns]
        if len(set(keys)) != len(keys):
            raise ValueError(f"{self.suite}: a column is declared twice")
        spec = self.spec(self.primary)
        if spec is None or spec.higher_is_better is None or not spec.table:
            raise ValueError(f"{self.suite}: the primary column {self.primary!r} must be a printed, ordered column")
        for c in self.columns:
            target = None if c.reference is None else self.spec(c.reference)
            if c.reference is not None and (c.table or target is None or not target.table or target.scale != c.scale):
                raise ValueError(f"{self.suite}: {c.key} must be unprinted and refer to a printed column of its "
                                 f"scale, not {c.reference!r}")

    def spec(self, key: str) -> ColumnSpec | None:
        return next((c for c in self.columns if c.key == key), None)

    def scale(self, key: str) -> float:
        spec = self.spec(key)
        return 1.0 if spec is None else spec.scale

    def higher_is_better(self, key: str) -> bool | None:
        spec = self.spec(key)
        return None if spec is None else spec.higher_is_better

    def table_columns(self, present: set[str] | None = None) -> list[ColumnSpec]:
        """Printed columns in order; with ``present``, only those keys."""
        return [c for c in self.columns if c.table and (present is None or c.key in present)]

    def references(self) -> dict[str, str]:
        """Ground-truth reference key -> the printed key it is shown under (see :class:`ColumnSpec`)."""
        return {c.key: c.reference for c in self.columns if c.reference is not None}

    def scaled(self, metrics: dict[str, float]) -> dict[str, float]:
        """Publication values of raw ``metrics``: raw × :meth:`scale` for every key."""
        return {k: v * self.scale(k) for k, v in metrics.items()}

    def scaling(self, metrics: dict[str, float]) -> dict[str, float]:
        """The scale of every key of ``metrics`` (what a result records beside ``scaled``)."""
        return {k: self.scale(k) for k in metrics}

    def directions(self, metrics) -> dict[str, bool | None]:
        """``higher_is_better`` of every key of ``metrics``."""
        return {k: self.higher_is_better(k) for k in metrics}


#: The suites whose modules declare ``COLUMNS`` (imported only when asked for).
SUITE_MODULES = {"dualtalk": "dyadbench.metrics.dualtalk", "l2l": "dyadbench.metrics.l2l",
                 "gaze": "dyadbench.metrics.gaze", "react": "dyadbench.metrics.react",
                 "seamless": "dyadbench.metrics.seamless"}


def declared(suite: str) -> SuiteColumns | None:
    """The declaration of a suite by name; None for a suite dyadbench does not know."""
    module = SUITE_MODULES.get(suite)
    return None if module is None else importlib.import_module(module).COLUMNS
