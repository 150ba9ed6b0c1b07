"""Score listener predictions with the Learning2Listen-line suite, from memory or from files on disk.

On disk: a folder of ``<clip>_listener.npy`` files or one ``.npz`` with those keys, each (T, 56) in
flame56 order [exp | jaw | head rotation], where ``<clip>`` is ``<host>_<split>_<n:05d>`` (window n of
the host's split, see :mod:`dyadbench.datasets.l2l`). The ground truth is an L2L root (or host folder);
the split defaults to ``test``. The suite is split-level (pooled statistics), so the predictions present
are scored together and coverage lists the missing ones. Bad input follows the policy of every suite
(:mod:`dyadbench.scoring.policy`): predictions with NaN/inf or fewer than two common frames are excluded
and listed, the pooled statistics are computed over the scored ones. A window whose speaker motion is
missing (a host folder without the speaking person's ``speak_faces`` array, or ``partner=None``) is scored
on every metric that does not need the speaker; P-FD and rPCC (:func:`dyadbench.metrics.l2l.partner_keys`)
leave it out, and it is listed under ``coverage["not_computable"]`` with the reason
(:mod:`dyadbench.scoring.without_partner`, as in the DualTalk suite).
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
from dyadbench.motion import FLAME56, l2l_to_flame56
from dyadbench.scoring import policy, without_partner
from dyadbench.scoring.predictions import open_predictions
from dyadbench.scoring.report import ScoreItem, ScoreReport

SUITE = "l2l"
MIN_FRAMES = 2  # the suite's per-sequence statistics need two frames
PARTNER_HEADERS = ", ".join(suite.HEADERS[m] for m in suite.NEEDS_PARTNER)


def columns(params: suite.L2LParams) -> list[ColumnSpec]:
    """The declared columns (:data:`dyadbench.metrics.l2l.COLUMNS`) of ``params``' components."""
    return [suite.COLUMNS.spec(k) for k in suite.keys(params)]


def _report(stems, preds, gts, speakers, *, expected, excluded, extra, warnings, seed, inputs,
            params, without_speaker: dict[str, str]) -> ScoreReport:
    """``without_speaker``: stem -> why its speaker motion is missing (its entry in ``speakers`` is None)."""
    stems, preds, gts, speakers, per_sequence = _sequence_metrics(stems, preds, gts, speakers, excluded, params)
    if not stems:
        raise policy.nothing_scored(inputs.get("pred"), excluded, extra, expected, warnings)
    metrics, per_sequence = suite.split_metrics(preds, gts, speakers, params, per_sequence)
    rows = [{"clip": stem, **values} for stem, values in zip(stems, per_sequence)]
    set_level = pooled_statistics(preds, gts, speakers, params)
    unavailable = {f"{m}_{c}": NO_UNCERTAINTY for m in ("si", "si_gt") for c in params.components}
    if all(a is None for a in speakers):
        unavailable.update({f"rpcc_{c}": NO_SPEAKER for c in params.components})
        set_level = {k: fn for k, fn in set_level.items() if k not in unavailable}
    spread, method = uncertainty.estimate(
        SUITE, rows, [f"{m}_{c}" for m in ("fd", "pfd") for c in params.components], seed=seed,
        set_level=set_level, unavailable=unavailable)
    present = set(stems) | {e["clip"] for e in excluded}
    not_computable = without_partner.not_computable(without_speaker, stems, suite.partner_keys(params))
    return ScoreReport(
        suite=SUITE, metrics=metrics, per_item=rows, excluded=excluded,
        coverage={"expected": len(expected), "scored": len(stems),
                  "missing": [s for s in expected if s not in present], "extra": extra,
                  "not_computable": not_computable},
        config={"suite": SUITE, **inputs, "seed": seed, "randomness": "k-means random_state (a parameter)",
                "parameters": params.as_dict(),
                "higher_is_better": suite.COLUMNS.directions(metrics),
                "truncation": "each sequence cut to the shortest of prediction, ground truth and speaker "
                              "(when present)",
                "versions": {"numpy": np.__version__, "scikit-learn": sklearn.__version__}},
        notes=policy.warning_notes(warnings) + policy.extra_notes(extra, expected)
        + without_partner.notes(not_computable, len(stems), PARTNER_HEADERS, aggregate="computed")
        + ["var and si are judged against var_gt and si_gt (the ground truth's own values)"],
        columns=columns(params), uncertainty=spread, uncertainty_method=method)


NO_UNCERTAINTY = "k-means is fitted on the pooled ground truth: a refit per bootstrap resample is too costly"
NO_SPEAKER = "no scored clip has the speaker's motion"


def pooled_statistics(preds, gts, speakers, params: suite.L2LParams) -> dict[str, uncertainty.SetStatistic]:
    """The pooled columns as functions of sequence weights w (B, N) (:mod:`dyadbench.uncertainty`; all
    ones: the split's values up to round-off), from per-sequence sums of the sequences cut to their common
    length: L2 = Σ w·SSE / Σ w·(T·d); Var = mean over dims of Σ w·Σx² / Σ w·T − (Σ w·Σx / Σ w·T)²;
    rPCC = |ρ(g, a) − ρ(p, a)| with ρ from the pooled sums of x, y, x², y², xy of the flattened entries
    (sequences without a speaker add nothing to them). SI is not among them (:data:`NO_UNCERTAINTY`)."""
    triples = [suite.cut(*t) for t in zip(preds, gts, speakers)]
    out: dict[str, uncertainty.SetStatistic] = {}
    for c in params.components:
        p, g, a = ([None if t[i] is None else FLAME56.component(np.asarray(t[i], np.float64), c) for t in triples]
                   for i in range(3))
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
    def sums(xs, ys) -> np.ndarray:  # (N, 6): n, Σx, Σy, Σx², Σy², Σxy per sequence (zeros without speaker)
        return np.array([[x.size, x.sum(), y.sum(), (x * x).sum(), (y * y).sum(), (x * y).sum()]
                         if y is not None else [0.0] * 6 for x, y in zip(xs, ys)], np.float64)

    def rho(w: np.ndarray, s: np.ndarray) -> np.ndarray:
        n, sx, sy, sxx, syy, sxy = (w @ s).T
        with np.errstate(invalid="ignore", divide="ignore"):  # a resample of windows without speaker: NaN
            return (sxy - sx * sy / n) / np.sqrt((sxx - sx * sx / n) * (syy - sy * sy / n))

    ga, pa = sums(g, a), sums(p, a)
    return lambda w: np.abs(rho(w, ga) - rho(w, pa))


def _sequence_metrics(stems, preds, gts, speakers, excluded, params):
    """Each sequence's metrics; a sequence whose metrics are undefined (e.g. a Fréchet distance with a large
    imaginary part) is left out and added to ``excluded`` with the reason, as in the DualTalk suite."""
    keep, rows = [], []
    for i, triple in enumerate(zip(preds, gts, speakers)):
        try:
            rows.append(suite.sequence_metrics(*suite.cut(*triple), params))
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
        common = min(len(pred), len(gts[i]), *([] if speakers[i] is None else [len(speakers[i])]))
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

    ``partner=None`` (the speaker's motion is missing): P-FD and rPCC leave that item out and it is listed
    under ``coverage["not_computable"]``; the other metrics are scored. ``jobs`` is accepted for a uniform
    interface (the suite is split-level and runs in one process).
    """
    if not items:
        raise InputError(None, "no items to score")
    preds, gts, speakers, names, warnings = [], [], [], [], []
    for item in items:
        names.append(item.pred_name)
        preds.append(check_motion(item.pred, item.pred_name, FLAME56.dim, finite=False))
        gts.append(check_motion(item.gt, item.gt_name, FLAME56.dim))
        speakers.append(None if item.partner is None else check_motion(item.partner, f"speaker of {item.stem}",
                                                                       FLAME56.dim))
        warnings += [policy.magnitude_warning(a, name, FLAME56)
                     for a, name in ((gts[-1], item.gt_name), (speakers[-1], f"speaker of {item.stem}"))
                     if a is not None]
    stems = [i.stem for i in items]
    without_speaker = {i.stem: "no speaker motion given (partner=None)" for i in items if i.partner is None}
    *kept, excluded, pred_warnings = _split_valid(stems, preds, names, gts, speakers)
    return _report(*kept, expected=stems, excluded=excluded, extra=[], warnings=warnings + pred_warnings,
                   seed=seed, inputs={"pred": "in-memory", "gt": "in-memory"}, params=params,
                   without_speaker=without_speaker)


def score_paths(pred: str | Path, gt: str | Path, *, split: str | None = None, jobs: int = 1,
                seed: int = 0) -> ScoreReport:
    """Score ``<clip>_listener`` predictions against an L2L root (split ``test`` unless given).

    A host folder without the speaking person's ``speak_faces`` array is scored without the speaker
    (:func:`score_arrays`' ``partner=None``), the missing file named in ``coverage["not_computable"]``.
    """
    split = split or "test"
    hosts = layout.host_splits(gt, split)
    expected, listener, speaker, without_speaker, warnings = _ground_truth(hosts, split)
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
                   params=suite.L2LParams(), without_speaker=without_speaker)


def _ground_truth(hosts: list[layout.HostSplit], split: str):
    """``(stems, listener, speaker, without_speaker, warnings)`` of the host splits: listener and speaker
    motion per window (flame56; speaker None for a host whose ``speak_faces`` array is missing),
    stem -> why its speaker is missing, and the motion files' magnitude warnings."""
    stems, listener, speaker, without_speaker, warnings = [], [], [], {}, []
    for hs in hosts:
        speaker_file = hs.path(1 - hs.listener, "speak_faces")
        if speaker_file.is_file():
            host_stems, host_listener, host_speaker = layout.stack_ground_truth([hs], split)
            speaker += list(host_speaker)
            files = hs.motion_files()
        else:
            host_listener = l2l_to_flame56(hs.listener_faces).astype(np.float64)
            host_stems = layout.window_stems(hs.host, split, len(host_listener))
            speaker += [None] * len(host_stems)
            without_speaker.update(dict.fromkeys(host_stems, f"speaker motion {speaker_file} not found"))
            files = [(hs.path(hs.listener, "list_faces"), hs.listener_faces)]
        stems += host_stems
        listener += list(host_listener)
        warnings += [policy.magnitude_warning(array[..., :layout.MOTION_DIM], path, FLAME56) for path, array in files]
    return stems, listener, speaker, without_speaker, warnings
