"""The bad-input policy of every metric suite (dualtalk, react, l2l, gaze): one set of rules, written once.

Each suite applies these rules through this module and the readers of :mod:`dyadbench.arrays`, in
this order and with the same wording, so a bad input has the same outcome whichever suite scores it:

1. **Files.** A path where a file is expected that is a folder ("is a folder, expected a file"), a
   symbolic link loop ("symbolic link loop"), a broken link or nothing; bytes that are not a NumPy file
   ("not a NumPy .npy/.npz file"); a pickled (object) array (never loaded); an ``.npz`` holding two
   members of the same name (duplicate key) -> error naming the file (and key).
2. **Shape.** An array that is not of the layout's shape ((T, D) per item; REACT predictions
   (R, T, 25)) -> error naming the array, its shape and the expected one (and whether it looks transposed).
3. **dtype.** Predictions and ground truth hold real floating-point numbers; an int, bool, complex,
   object or string array -> error naming the file (and key).
4. **NaN/inf.** In ground truth -> error naming the file. In a prediction -> the prediction is
   *excluded*: not scored, listed under the report's ``excluded`` with a reason that names the file;
   ``dyadbench score --strict`` then fails. A prediction with too few frames for the suite is excluded
   the same way. (Gaze-head sessions mark tracker loss with ``valid=False``; NaN is allowed in those
   frames only, which the layout drops.)
5. **Overflow.** A finite value whose square overflows float64 (\\|x\\| > 1.34e154), in ground truth or
   in a prediction -> error naming the file: no metric can be computed from it.
6. **Implausible magnitudes.** A value beyond the layout's plausible range
   (:attr:`dyadbench.motion.MotionLayout.plausible_abs`: 100 for FLAME coefficients and radians, 360
   for degrees, 10 for REACT's emotion features, which lie in [-1, 1]) in ground truth or in a prediction
   -> a warning naming the file, kept in the report's ``notes`` (prefix ``warning: ``) and printed on
   stderr by ``dyadbench score``; the scores are still computed, and are dominated by those values.
7. **Coverage.** A ground-truth item without a prediction is listed in ``coverage["missing"]``
   (``--strict`` fails). A prediction without ground truth is listed in ``coverage["extra"]`` and
   named in a note; it is never scored and never fatal. When no prediction can be scored at all, the
   error says why (excluded ones with their reasons, extra ones with an expected name).

**Joint metrics.** Split-level metrics are computed over the scored predictions only: the L2L line's
pooled statistics, the gaze suite's pooled fixation and compensation ratios and its shuffled-speech
BAS reference, and REACT's metrics that couple samples. For REACT an excluded (or missing) sample's
prediction leaves every per-sample mean (FRCorr, FRDist, FRDiv, FRVar, FRSyn) and FRDvs, whose pairs
are formed among the scored samples only; its listener's real reaction stays in the pool of appropriate
reactions of the other samples (the neighbour matrix keeps all its columns).
"""

from __future__ import annotations

from pathlib import Path
from typing import Iterable

import numpy as np

from dyadbench.arrays import check_values, max_abs, nonfinite_problem, require_no_overflow
from dyadbench.errors import InputError
from dyadbench.motion import MotionLayout

#: Prefix of a note that is a warning (printed on stderr by ``dyadbench score``).
WARNING = "warning: "


#: Rules 4-5 for ground truth already checked for shape and dtype: NaN/inf or overflowing values raise
#: :class:`InputError` naming the source. The dataset readers apply the same function.
check_ground_truth = check_values


def exclusion(array: np.ndarray, source: str | Path) -> str | None:
    """Rules 4-5 for a prediction already checked for shape and dtype: the reason it is excluded (it
    holds NaN/inf; the reason names ``source``), or None when it can be scored. Overflowing finite
    values raise :class:`InputError`."""
    problem = nonfinite_problem(np.asarray(array))
    if problem:
        return f"{problem} in {source}"
    require_no_overflow(array, source)
    return None


def too_short(source: str | Path, frames: int, needed: int, counted: str = "frames") -> str:
    """The exclusion reason of a prediction with too few frames to be scored (``counted`` says which
    frames count, e.g. "common frames")."""
    return f"only {frames} {counted} in {source}; the suite needs at least {needed}"


def magnitude_warning(array: np.ndarray, source: str | Path, layout: MotionLayout) -> str | None:
    """Rule 6: the warning for values beyond ``layout.plausible_abs`` (naming ``source``), or None."""
    largest = max_abs(array)
    if largest <= layout.plausible_abs:
        return None
    return (f"{source}: values up to {largest:.3g} in magnitude, beyond the plausible {layout.plausible_abs:g} for "
            f"{layout.name} motion ({layout.units}); the scores involving it are dominated by them")


def warning_notes(warnings: Iterable[str | None]) -> list[str]:
    """Report notes for the given warnings (None skipped, each once, in order), prefixed :data:`WARNING`."""
    return [WARNING + w for w in dict.fromkeys(w for w in warnings if w)]


def extra_notes(extra: list[str], expected: list[str]) -> list[str]:
    """Rule 7: the note naming predictions without ground truth (none when there are none), with an
    example of the names the ground truth has."""
    if not extra:
        return []
    shown = ", ".join(extra[:5]) + (f", … ({len(extra) - 5} more)" if len(extra) > 5 else "")
    example = f"; ground-truth items are named like {expected[0]}" if expected else ""
    return [f"{len(extra)} prediction(s) without ground truth were not scored (listed under coverage.extra): "
            f"{shown}{example}"]


def collect(outcomes: Iterable) -> tuple[list[dict], list[dict], list[str]]:
    """(rows, excluded, warnings) of per-item scoring outcomes (each with ``stem``, ``metrics``, ``excluded``
    and ``warnings``): a row ``{"clip": stem, **metrics}`` per scored item, ``{"clip", "reason"}`` per excluded
    one, and every warning, in order."""
    rows, excluded, warnings = [], [], []
    for outcome in outcomes:
        warnings += outcome.warnings
        if outcome.excluded is not None:
            excluded.append({"clip": outcome.stem, "reason": outcome.excluded})
        else:
            rows.append({"clip": outcome.stem, **outcome.metrics})
    return rows, excluded, warnings


def nothing_scored(pred: str | Path | None, excluded: list[dict], extra: list[str], expected: list[str],
                   warnings: Iterable[str | None] = ()) -> InputError:
    """Rule 7: the error when no prediction can be scored, saying why (with the magnitude warnings, which
    often are the reason)."""
    reasons = [f"{e['clip']}: {e['reason']}" for e in excluded[:5]]
    if extra:
        reasons.append(f"{len(extra)} named like no ground-truth item (e.g. {extra[0]}; expected names like "
                       f"{expected[0] if expected else '?'})")
    reasons += warning_notes(warnings)
    return InputError(pred, f"no prediction could be scored ({'; '.join(reasons) or 'none given'})")
