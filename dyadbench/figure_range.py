"""The value axis of a figure panel: which trivial series are drawn off-scale so the models' differences show.

A trivial baseline can sit far from every model (``zero``'s FD exp of 65 against models between 4 and 20), and an
axis that holds it squeezes the models into a sliver. The rule, per panel:

- the *core* range [lo, hi] is spanned by the non-trivial series (models, their variants, the oracle);
- its *reach* r = max(hi - lo, |lo|, |hi|): the core's width, or its largest magnitude when that is larger
  (so a tight cluster of models far from 0 does not push a baseline at a moderately different value off the
  axis);
- a trivial series (a registered baseline) with a value outside [lo - r, hi + r] is *off-scale*: the axis
  covers the other series only, the off-scale values are drawn at the axis edge and the value is written
  there (``zero 65.3 ↑``).

For non-negative metrics with the oracle at 0 this reads: a baseline more than twice the largest model
value is off-scale. Nothing is off-scale when the panel has no non-trivial series or r = 0.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Collection, Iterable, Mapping

#: Fraction of the kept width added as a margin on each side, and as the band holding off-scale series.
MARGIN = 0.05
BAND = 0.16


@dataclass(frozen=True)
class ValueRange:
    """``low``/``high``: the extent of the series kept on the axis; ``above``/``below``: off-scale series
    (label -> its most extreme value) beyond the high and the low end."""

    low: float
    high: float
    above: dict[str, float]
    below: dict[str, float]

    def limits(self) -> tuple[float, float]:
        """Axis limits: the kept extent with a :data:`MARGIN` each side, widened by a :data:`BAND` on each
        side that holds off-scale series (drawn at the limit)."""
        width = self.high - self.low or abs(self.high) or 1.0
        low = self.low - (BAND if self.below else MARGIN) * width
        high = self.high + (BAND if self.above else MARGIN) * width
        return low, high


def value_range(series: Mapping[str, Iterable[float]], trivial: Collection[str]) -> ValueRange:
    """The :class:`ValueRange` of a panel's ``series`` (label -> values; NaN ignored) where the labels in
    ``trivial`` may go off-scale (see the module docstring). ValueError when no series has a finite value."""
    values = {label: [float(v) for v in vals if math.isfinite(float(v))] for label, vals in series.items()}
    values = {label: vals for label, vals in values.items() if vals}
    if not values:
        raise ValueError("no finite value to draw")
    core = [v for label, vals in values.items() if label not in trivial for v in vals]
    above, below = {}, {}
    if core:
        lo, hi = min(core), max(core)
        reach = max(hi - lo, abs(lo), abs(hi))
        if reach > 0:
            above = {label: max(vals) for label, vals in values.items()
                     if label in trivial and max(vals) > hi + reach}
            below = {label: min(vals) for label, vals in values.items()
                     if label in trivial and min(vals) < lo - reach}
    kept = [v for label, vals in values.items() if label not in above and label not in below for v in vals]
    return ValueRange(min(kept), max(kept), above, below)


def off_scale_note(off: Mapping[str, float], arrow: str) -> str:
    """``zero 65.3 ↑`` (one entry per series, by value; three significant digits)."""
    return ", ".join(f"{label} {value:.3g} {arrow}" for label, value in
                     sorted(off.items(), key=lambda item: -abs(item[1])))
