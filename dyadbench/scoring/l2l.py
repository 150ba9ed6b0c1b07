"""Score listener predictions with the Learning2Listen-line suite, from memory or from files on disk.

On disk: a folder of ``<clip>_listener.npy`` files or one ``.npz`` with those keys, each (T, 56) in
flame56 order [exp | jaw | head rotation], where ``<clip>`` is ``<host>_<split>_<n:05d>`` (window n of
the host's split, see :mod:`dyadbench.datasets.l2l`). The ground truth is an L2L root (or host folder);
the split defaults to ``test``. The suite is split-level (pooled statistics), so the predictions present
are scored together and coverage lists the missing ones; predictions with NaN/inf are excluded and listed.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import sklearn

from dyadbench.arrays import nonfinite_count
from dyadbench.datasets import l2l as layout
from dyadbench.errors import InputError
from dyadbench.metrics import l2l as suite
from dyadbench.motion import FLAME56
from dyadbench.scoring.predictions import open_predictions
from dyadbench.scoring.report import Column, ScoreItem, ScoreReport

SUITE = "l2l"
HEADERS = {"l2": "L2", "fd": "FD", "pfd": "P-FD", "var": "Var", "var_gt": "Var-GT", "si": "SI", "si_gt": "SI-GT",
           "rpcc": "rPCC"}


def columns(params: suite.L2LParams) -> list[Column]:
    return [Column(f"{m}_{c}", f"{HEADERS[m]} {c}") for m in suite.METRIC_NAMES for c in params.components]


def _report(stems, preds, gts, speakers, *, expected, excluded, extra, seed, inputs, params) -> ScoreReport:
    if not stems:
        reasons = "; ".join(f"{e['clip']}: {e['reason']}" for e in excluded[:5])
        raise InputError(inputs.get("pred"), f"no prediction could be scored ({reasons or 'none given'})")
    metrics, per_sequence = suite.split_metrics(preds, gts, speakers, params)
    rows = [{"clip": stem, **values} for stem, values in zip(stems, per_sequence)]
    present = set(stems) | {e["clip"] for e in excluded}
    return ScoreReport(
        suite=SUITE, metrics=metrics, scaled=dict(metrics), per_item=rows, excluded=excluded,
        coverage={"expected": len(expected), "scored": len(stems),
                  "missing": [s for s in expected if s not in present], "extra": extra},
        config={"suite": SUITE, **inputs, "seed": seed, "randomness": "k-means random_state (a parameter)",
                "parameters": params.as_dict(),
                "higher_is_better": {f"{m}_{c}": suite.HIGHER_IS_BETTER[m] for m in suite.METRIC_NAMES
                                     for c in params.components},
                "truncation": "each sequence cut to the shortest of prediction, ground truth and speaker",
                "versions": {"numpy": np.__version__, "scikit-learn": sklearn.__version__}},
        notes=["var and si are judged against var_gt and si_gt (the ground truth's own values)"],
        columns=columns(params))


def _split_valid(stems, preds, gts, speakers):
    keep, excluded = [], []
    for i, (stem, pred) in enumerate(zip(stems, preds)):
        bad = nonfinite_count(np.asarray(pred))
        if bad:
            excluded.append({"clip": stem, "reason": f"{bad} NaN/inf values in the prediction"})
        else:
            keep.append(i)
    stems, preds, gts, speakers = ([xs[i] for i in keep] for xs in (stems, preds, gts, speakers))
    return stems, preds, gts, speakers, excluded


def score_arrays(items: list[ScoreItem], *, jobs: int = 1, seed: int = 0,
                 params: suite.L2LParams = suite.L2LParams()) -> ScoreReport:
    """Score in-memory listener predictions: ``pred`` and ``gt`` (T, 56), ``partner`` = the speaker (T, 56).

    ``jobs`` is accepted for a uniform interface (the suite is split-level and runs in one process).
    """
    if not items:
        raise InputError(None, "no items to score")
    for item in items:
        if item.partner is None:
            raise InputError(item.stem, "the L2L suite needs the speaker's motion (partner=None)")
        for name, a in (("prediction", item.pred), ("ground truth", item.gt), ("speaker", item.partner)):
            if np.ndim(a) != 2 or np.shape(a)[1] != FLAME56.dim:
                raise InputError(f"{item.stem} {name}", f"expected (T, {FLAME56.dim}), got {np.shape(a)}")
    stems = [i.stem for i in items]
    kept = _split_valid(stems, [i.pred for i in items], [i.gt for i in items], [i.partner for i in items])
    return _report(*kept[:4], expected=stems, excluded=kept[4], extra=[], seed=seed,
                   inputs={"pred": "in-memory", "gt": "in-memory"}, params=params)


def score_paths(pred: str | Path, gt: str | Path, *, split: str | None = None, jobs: int = 1,
                seed: int = 0) -> ScoreReport:
    """Score ``<clip>_listener`` predictions against an L2L root (split ``test`` unless given)."""
    split = split or "test"
    expected, listener, speaker = layout.ground_truth(gt, split)
    index = {stem: i for i, stem in enumerate(expected)}
    predictions = open_predictions(pred)
    extra = sorted(s for s in predictions if s not in index)
    stems = [s for s in predictions if s in index]
    if not stems:
        raise InputError(pred, f"no prediction named like the {split} windows (<host>_{split}_<n>_listener), "
                               f"e.g. {expected[0]}")
    preds = [predictions[s].load(FLAME56.dim) for s in stems]
    gts = [listener[index[s]] for s in stems]
    spk = [speaker[index[s]] for s in stems]
    kept = _split_valid(stems, preds, gts, spk)
    return _report(*kept[:4], expected=expected, excluded=kept[4], extra=extra, seed=seed,
                   inputs={"pred": str(pred), "gt": str(gt), "split": split}, params=suite.L2LParams())
