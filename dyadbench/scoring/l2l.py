"""Score listener predictions with the Learning2Listen-line suite, from memory or from files on disk.

On disk: a folder of ``<clip>_listener.npy`` files or one ``.npz`` with those keys, each (T, 56) in
flame56 order [exp | jaw | head rotation], where ``<clip>`` is ``<host>_<split>_<n:05d>`` (window n of
the host's split, see :mod:`dyadbench.datasets.l2l`). The ground truth is an L2L root (or host folder);
the split defaults to ``test``. The suite is split-level (pooled statistics), so the predictions present
are scored together and coverage lists the missing ones. Bad input follows the policy of every suite
(:mod:`dyadbench.scoring.policy`): predictions with NaN/inf or fewer than two common frames are excluded
and listed, the pooled statistics are computed over the scored ones.
Uncertainty (:mod:`dyadbench.uncertainty`; every window its own dialogue): FD and P-FD are means over
sequences (cluster-robust s.e., bootstrap CI); L2, Var and rPCC are recomputed on every resample from
per-sequence sums (:func:`pooled_statistics`); SI has none (:data:`NO_UNCERTAINTY`).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import sklearn

from dyadbench import uncertainty
from dyadbench.arrays import check_motion
from dyadbench.datasets import l2l as layout
from dyadbench.errors import InputError
from dyadbench.metrics import l2l as suite
from dyadbench.metrics.columns import ColumnSpec
from dyadbench.metrics.dualtalk import truncate_to_shortest
from dyadbench.motion import FLAME56
from dyadbench.scoring import policy
from dyadbench.scoring.predictions import open_predictions
from dyadbench.scoring.report import ScoreItem, ScoreReport

SUITE = "l2l"
MIN_FRAMES = 2  # the suite's per-sequence statistics need two frames


def columns(params: suite.L2LParams) -> list[ColumnSpec]:
    """The declared columns (:data:`dyadbench.metrics.l2l.COLUMNS`) of ``params``' components."""
    return [suite.COLUMNS.spec(k) for k in suite.keys(params)]


def _report(stems, preds, gts, speakers, *, expected, excluded, extra, warnings, seed, inputs,
            params) -> ScoreReport:
    stems, preds, gts, speakers, per_sequence = _sequence_metrics(stems, preds, gts, speakers, excluded, params)
    if not stems:
        raise policy.nothing_scored(inputs.get("pred"), excluded, extra, expected, warnings)
    metrics, per_sequence = suite.split_metrics(preds, gts, speakers, params, per_sequence)
    rows = [{"clip": stem, **values} for stem, values in zip(stems, per_sequence)]
    spread, method = uncertainty.estimate(
        SUITE, rows, [f"{m}_{c}" for m in ("fd", "pfd") for c in params.components], seed=seed,
        set_level=pooled_statistics(preds, gts, speakers, params),
        unavailable={f"{m}_{c}": NO_UNCERTAINTY for m in ("si", "si_gt") for c in params.components})
    present = set(stems) | {e["clip"] for e in excluded}
    return ScoreReport(
        suite=SUITE, metrics=metrics, per_item=rows, excluded=excluded,
        coverage={"expected": len(expected), "scored": len(stems),
                  "missing": [s for s in expected if s not in present], "extra": extra},
        config={"suite": SUITE, **inputs, "seed": seed, "randomness": "k-means random_state (a parameter)",
                "parameters": params.as_dict(),
                "higher_is_better": suite.COLUMNS.directions(metrics),
                "truncation": "each sequence cut to the shortest of prediction, ground truth and speaker",
                "versions": {"numpy": np.__version__, "scikit-learn": sklearn.__version__}},
        notes=policy.warning_notes(warnings) + policy.extra_notes(extra, expected)
        + ["var and si are judged against var_gt and si_gt (the ground truth's own values)"],
        columns=columns(params), uncertainty=spread, uncertainty_method=method)


NO_UNCERTAINTY = "k-means is fitted on the pooled ground truth: a refit per bootstrap resample is too costly"


def pooled_statistics(preds, gts, speakers, params: suite.L2LParams) -> dict[str, uncertainty.SetStatistic]:
    """The pooled columns as functions of sequence weights w (B, N) (:mod:`dyadbench.uncertainty`; all
    ones: the split's values up to round-off), from per-sequence sums of the sequences cut to their common
    length: L2 = Σ w·SSE / Σ w·(T·d); Var = mean over dims of Σ w·Σx² / Σ w·T − (Σ w·Σx / Σ w·T)²;
    rPCC = |ρ(g, a) − ρ(p, a)| with ρ from the pooled sums of x, y, x², y², xy of the flattened entries.
    SI is not among them (:data:`NO_UNCERTAINTY`)."""
    triples = [truncate_to_shortest(*t) for t in zip(preds, gts, speakers)]
    out: dict[str, uncertainty.SetStatistic] = {}
    for c in params.components:
        p, g, a = ([FLAME56.component(np.asarray(t[i], np.float64), c) for t in triples] for i in range(3))
        out[f"l2_{c}"] = uncertainty.ratio([np.sum((x - y) ** 2) for x, y in zip(p, g)], [x.size for x in p])
        out[f"var_{c}"], out[f"var_gt_{c}"] = _pooled_variance(p), _pooled_variance(g)
        out[f"rpcc_{c}"] = _pooled_rpcc(p, g, a)
    return out


def _pooled_variance(xs: list[np.ndarray]) -> uncertainty.SetStatistic:
    frames = np.array([len(x) for x in xs], np.float64)
    first = np.stack([x.sum(axis=0) for x in xs])
    second = np.stack([(x ** 2).sum(axis=0) for x in xs])

    def var(w: np.ndarray) -> np.ndarray:
        n = (w @ frames)[:, None]
        return ((w @ second) / n - ((w @ first) / n) ** 2).mean(axis=1)
    return var


def _pooled_rpcc(p: list[np.ndarray], g: list[np.ndarray], a: list[np.ndarray]) -> uncertainty.SetStatistic:
    def sums(xs, ys) -> np.ndarray:  # (N, 6): n, Σx, Σy, Σx², Σy², Σxy per sequence
        return np.array([[x.size, x.sum(), y.sum(), (x * x).sum(), (y * y).sum(), (x * y).sum()]
                         for x, y in zip(xs, ys)], np.float64)

    def rho(w: np.ndarray, s: np.ndarray) -> np.ndarray:
        n, sx, sy, sxx, syy, sxy = (w @ s).T
        return (sxy - sx * sy / n) / np.sqrt((sxx - sx * sx / n) * (syy - sy * sy / n))

    ga, pa = sums(g, a), sums(p, a)
    return lambda w: np.abs(rho(w, ga) - rho(w, pa))


def _sequence_metrics(stems, preds, gts, speakers, excluded, params):
    """Each sequence's metrics; a sequence whose metrics are undefined (e.g. a Fréchet distance with a large
    imaginary part) is left out and added to ``excluded`` with the reason, as in the DualTalk suite."""
    keep, rows = [], []
    for i, triple in enumerate(zip(preds, gts, speakers)):
        try:
            rows.append(suite.sequence_metrics(*truncate_to_shortest(*triple), params))
            keep.append(i)
        except ValueError as exc:
            excluded.append({"clip": stems[i], "reason": f"could not be scored: {exc}"})
    return *([xs[i] for i in keep] for xs in (stems, preds, gts, speakers)), rows


def _split_valid(stems, preds, names, gts, speakers):
    """The scorable sequences (:mod:`dyadbench.scoring.policy`: NaN/inf or fewer than 2 common frames are
    excluded), the excluded ones with their reasons, and the predictions' magnitude warnings."""
    keep, excluded, warnings = [], [], []
    for i, (stem, pred, name) in enumerate(zip(stems, preds, names)):
        reason = policy.exclusion(pred, name)
        common = min(len(pred), len(gts[i]), len(speakers[i]))
        if reason is None and common < MIN_FRAMES:
            reason = policy.too_short(name, common, MIN_FRAMES, "common frames")
        if reason is None:
            keep.append(i)
            warnings.append(policy.magnitude_warning(pred, name, FLAME56))
        else:
            excluded.append({"clip": stem, "reason": reason})
    stems, preds, gts, speakers = ([xs[i] for i in keep] for xs in (stems, preds, gts, speakers))
    return stems, preds, gts, speakers, excluded, warnings


def score_arrays(items: list[ScoreItem], *, jobs: int = 1, seed: int = 0,
                 params: suite.L2LParams = suite.L2LParams()) -> ScoreReport:
    """Score in-memory listener predictions: ``pred`` and ``gt`` (T, 56), ``partner`` = the speaker (T, 56).

    ``jobs`` is accepted for a uniform interface (the suite is split-level and runs in one process).
    """
    if not items:
        raise InputError(None, "no items to score")
    preds, gts, speakers, names, warnings = [], [], [], [], []
    for item in items:
        if item.partner is None:
            raise InputError(item.stem, "the L2L suite needs the speaker's motion (partner=None)")
        names.append(item.pred_name)
        preds.append(check_motion(item.pred, item.pred_name, FLAME56.dim, finite=False))
        for name, array, out in ((item.gt_name, item.gt, gts), (f"speaker of {item.stem}", item.partner, speakers)):
            out.append(check_motion(array, name, FLAME56.dim))
            warnings.append(policy.magnitude_warning(out[-1], name, FLAME56))
    stems = [i.stem for i in items]
    *kept, excluded, pred_warnings = _split_valid(stems, preds, names, gts, speakers)
    return _report(*kept, expected=stems, excluded=excluded, extra=[], warnings=warnings + pred_warnings,
                   seed=seed, inputs={"pred": "in-memory", "gt": "in-memory"}, params=params)


def score_paths(pred: str | Path, gt: str | Path, *, split: str | None = None, jobs: int = 1,
                seed: int = 0) -> ScoreReport:
    """Score ``<clip>_listener`` predictions against an L2L root (split ``test`` unless given)."""
    split = split or "test"
    hosts = layout.host_splits(gt, split)
    expected, listener, speaker = layout.stack_ground_truth(hosts, split)
    warnings = [policy.magnitude_warning(array[..., :layout.MOTION_DIM], path, FLAME56)
                for hs in hosts for path, array in hs.motion_files()]
    index = {stem: i for i, stem in enumerate(expected)}
    predictions = open_predictions(pred)
    extra = sorted(s for s in predictions if s not in index)
    stems = [s for s in predictions if s in index]
    preds = [predictions[s].load(FLAME56.dim) for s in stems]
    names = [predictions[s].name for s in stems]
    gts = [listener[index[s]] for s in stems]
    spk = [speaker[index[s]] for s in stems]
    *kept, excluded, pred_warnings = _split_valid(stems, preds, names, gts, spk)
    return _report(*kept, expected=expected, excluded=excluded, extra=extra, warnings=warnings + pred_warnings,
                   seed=seed, inputs={"pred": str(pred), "gt": str(gt), "split": split},
                   params=suite.L2LParams())
