"""Which term limits SimWithGT: its FixRatio gap and its CompScore gap, and the score with either one closed.

SimWithGT (:func:`dyadbench.metrics.gaze.sim_with_gt`, the paper's eq. 8) is
``1 - (|Fix_GT - Fix_pred| + |Comp_GT - Comp_pred|)``: a sum of two independent gaps. Holding one term at
the ground truth's value isolates the other:

- ``sim_fix_gt``  = SimWithGT with the prediction's FixRatio replaced by GT's (its CompScore kept)
  = ``1 - comp_gap``;
- ``sim_comp_gt`` = SimWithGT with the prediction's CompScore replaced by GT's (its FixRatio kept)
  = ``1 - fix_gap``.

The limiting term is the larger gap. Example: GT (0.60, -0.33), prediction (0.90, -0.20) gives
fix_gap 0.30, comp_gap 0.13, SimWithGT 0.57, 0.87 with GT's FixRatio, 0.70 with GT's CompScore: FixRatio
limits it. Pure functions, numbers in and out.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

from dyadbench.errors import InputError
from dyadbench.metrics.gaze import sim_with_gt


@dataclass(frozen=True)
class SimTerms:
    """SimWithGT of one prediction split into its two gaps (FixRatio as a fraction, CompScore in its unit)."""

    sim: float
    fix_gap: float
    comp_gap: float
    sim_fix_gt: float
    sim_comp_gt: float

    @property
    def limiting(self) -> str:
        """``"FixRatio"`` or ``"CompScore"``: the term with the larger gap (``"tie"`` if equal)."""
        if self.fix_gap == self.comp_gap:
            return "tie"
        return "FixRatio" if self.fix_gap > self.comp_gap else "CompScore"

    def as_dict(self) -> dict:
        return {**asdict(self), "limiting": self.limiting}


def sim_terms(fix_gt: float, comp_gt: float, fix_pred: float, comp_pred: float) -> SimTerms:
    """The two gaps of SimWithGT and the score with each term set to the ground truth's.

    Raises :class:`InputError` if any value is not finite (a NaN FixRatio means no labelled frame).
    """
    values = {"fix_gt": fix_gt, "comp_gt": comp_gt, "fix_pred": fix_pred, "comp_pred": comp_pred}
    bad = [k for k, v in values.items() if not math.isfinite(v)]
    if bad:
        raise InputError("SimWithGT terms", f"non-finite {', '.join(bad)}: {values}")
    return SimTerms(sim=sim_with_gt(fix_gt, comp_gt, fix_pred, comp_pred),
                    fix_gap=abs(fix_gt - fix_pred), comp_gap=abs(comp_gt - comp_pred),
                    sim_fix_gt=sim_with_gt(fix_gt, comp_gt, fix_gt, comp_pred),
                    sim_comp_gt=sim_with_gt(fix_gt, comp_gt, fix_pred, comp_gt))
