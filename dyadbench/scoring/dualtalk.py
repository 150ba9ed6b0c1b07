"""Score predictions with the DualTalk/TIMAR suite, from memory or from files on disk.

:func:`score_arrays` takes in-memory :class:`~dyadbench.scoring.report.ScoreItem` s;
:func:`score_paths` takes a prediction folder (or ``.npz``) and a DualTalk split folder. Both go
through the same per-item job (:func:`_score_job`) and the same report builder, so they give
identical numbers for identical data.

Per item: the prediction, the agent's ground truth and the partner's ground truth are validated
with the bad-input policy of every suite (:mod:`dyadbench.scoring.policy`), truncated to the shortest
length (counted), and scored with :func:`dyadbench.metrics.dualtalk.clip_metrics` seeded by
``derive_seed(seed, stem)``. Predictions with NaN/inf values or fewer than
:data:`~dyadbench.metrics.dualtalk.MIN_FRAMES` common frames are excluded and listed with the reason;
predictions without ground truth are listed as extra. A prediction whose partner's ground truth is missing
(the released DualTalk demo clips each ship one participant's ``.npz``) is scored on every metric that does
not need the partner; its partner-based keys (P-FD, rPCC:
:data:`~dyadbench.metrics.dualtalk.PARTNER_KEYS`) are NaN, listed under ``coverage["not_computable"]``
with the reason and left out of those keys' means. Aggregation is the plain mean over clips; every
column's standard error and bootstrap CI resample dialogues (both speakers of a clip together,
:mod:`dyadbench.uncertainty`).
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import scipy
import sklearn

from dyadbench import uncertainty
from dyadbench.arrays import check_motion
from dyadbench.datasets.dualtalk_files import load_gt_npz
from dyadbench.errors import InputError
from dyadbench.metrics import dualtalk as suite
from dyadbench.metrics.columns import ColumnSpec
from dyadbench.motion import FLAME56
from dyadbench.scoring import policy, without_partner
from dyadbench.scoring.parallel import THREADS_PER_JOB, map_items
from dyadbench.scoring.predictions import PredictionFile, open_predictions
from dyadbench.scoring.report import ScoreItem, ScoreReport
from dyadbench.scoring.stored import StoredItem
from dyadbench.seeding import derive_seed

SUITE = "dualtalk"
#: score_arrays accepts StoredItem s and reads each one only when scoring it (dyadbench.scoring.stored).
STREAMS_ITEMS = True
AGENT_STEM = re.compile(r"^(?P<clip>.+)_speaker(?P<k>[12])$")

DIVERSITY_SEED_RULE = (
    "component i (exp 0, jaw 1, pose 2) of clip <stem>: numpy.random.default_rng([derive_seed(seed, stem), i])"
    " draws 100 frame indices without replacement twice (u, then v); the prediction and the ground truth use "
    "the same draws (derive_seed = dyadbench.seeding.derive_seed)")

UNDEFINED_REASONS = {
    "div_pred": f"fewer than {suite.DIVERSITY_TIMES} frames",
    "div_gt": f"fewer than {suite.DIVERSITY_TIMES} frames",
    "rpcc": "constant motion, correlation undefined",
}


@dataclass(frozen=True)
class _Job:
    """One agent to score: arrays in memory, where to read them (a prediction file, npz paths), or a
    :class:`StoredItem` (``stored``; ``pred``, ``gt`` and ``partner`` None) read when the job runs."""

    stem: str
    seed: int
    pred: np.ndarray | PredictionFile | None
    gt: np.ndarray | Path | None
    partner: np.ndarray | Path | None  # None: the partner's ground truth is missing
    partner_missing: str = ""  # why the partner's ground truth is missing (non-empty exactly when it is)
    stored: StoredItem | None = None


@dataclass
class _Outcome:
    stem: str
    frames: dict[str, int] = field(default_factory=dict)
    metrics: dict[str, float] | None = None
    excluded: str | None = None
    warnings: list[str | None] = field(default_factory=list)


def _load_ground_truth(value: np.ndarray | Path, name: str) -> tuple[np.ndarray, str]:
    """(T, 56) ground truth and how messages name it (the file, or ``name`` for an in-memory array)."""
    if isinstance(value, Path):
        return load_gt_npz(value), str(value)
    return check_motion(value, name, FLAME56.dim), name


def _load_prediction(job: _Job) -> tuple[np.ndarray, str]:
    if isinstance(job.pred, PredictionFile):
        return job.pred.load(FLAME56.dim), job.pred.name
    name = f"prediction {job.stem}"
    return check_motion(job.pred, name, FLAME56.dim, finite=False), name


def _score_job(job: _Job) -> _Outcome:
    """Load, validate (:mod:`dyadbench.scoring.policy`) and score one agent. Runs in a worker: an error is
    raised there and reaches the caller unchanged."""
    if job.stored is not None:
        item = job.stored.load()
        job = _Job(job.stem, job.seed, item.pred, item.gt, item.partner, job.partner_missing)
    pred, pred_name = _load_prediction(job)
    gt, gt_name = _load_ground_truth(job.gt, f"ground truth of {job.stem}")
    outcome = _Outcome(job.stem, frames={"pred": pred.shape[0], "gt": gt.shape[0]})
    scored = [(gt, gt_name)]
    partner = None
    if job.partner is not None:
        partner, partner_name = _load_ground_truth(job.partner, f"partner ground truth of {job.stem}")
        outcome.frames["partner"] = partner.shape[0]
        scored.append((partner, partner_name))
    outcome.excluded = policy.exclusion(pred, pred_name)
    scored += [(pred, pred_name)] if outcome.excluded is None else []
    outcome.warnings = [policy.magnitude_warning(a, name, FLAME56) for a, name in scored]
    common = min(outcome.frames.values())
    if outcome.excluded is None and common < suite.MIN_FRAMES:
        outcome.excluded = policy.too_short(pred_name, common, suite.MIN_FRAMES, "common frames")
    if outcome.excluded is None:
        try:
            outcome.metrics = suite.clip_metrics(pred, gt, partner, seed=job.seed)
        except ValueError as exc:  # e.g. a Fréchet distance with a large imaginary part (reference: crash)
            outcome.excluded = f"could not be scored: {exc}"
    return outcome


def columns() -> list[ColumnSpec]:
    """Printed columns: every declared key (:data:`dyadbench.metrics.dualtalk.COLUMNS`) in the DualTalk/TIMAR
    table order, then dyadbench's extra columns."""
    return list(suite.COLUMNS.columns)


def _aggregate(rows: list[dict], without_partner: set[str]) -> tuple[dict[str, float], dict[str, list[str]]]:
    """Mean over clips of each key, leaving out clips where the value is NaN; those are listed as undefined,
    except the partner-based keys of clips ``without_partner`` (listed as not computable instead)."""
    means, undefined = {}, {}
    for key in suite.KEYS:
        values = np.array([row[key] for row in rows], dtype=np.float64)
        defined = np.isfinite(values)
        means[key] = float(values[defined].mean()) if defined.any() else math.nan
        skipped = without_partner if key in suite.PARTNER_KEYS else set()
        clips = [row["clip"] for row, ok in zip(rows, defined) if not ok and row["clip"] not in skipped]
        if clips:
            undefined[key] = clips
    return means, undefined


PARTNER_HEADERS = ", ".join(m.header for m in suite.METRICS if m.needs_partner)


def _undefined_notes(undefined: dict[str, list[str]], n_scored: int) -> list[str]:
    notes = []
    for key, clips in undefined.items():
        name = key.rsplit("_", 1)[0]
        reason = UNDEFINED_REASONS.get(name, "not a finite number")
        shown = ", ".join(clips[:3]) + (", …" if len(clips) > 3 else "")
        notes.append(f"{key} undefined for {len(clips)} of {n_scored} clips ({reason}: {shown}); "
                     f"its mean is over the other clips")
    return notes


def _run(jobs_list: list[_Job], *, jobs: int, seed: int, expected: list[str], inputs: dict,
         extra: list[str]) -> ScoreReport:
    outcomes = list(map_items(_score_job, jobs_list, jobs=jobs, desc="dualtalk"))
    truncated = [{"clip": o.stem, **o.frames, "used": min(o.frames.values())}
                 for o in outcomes if len(set(o.frames.values())) > 1]
    rows, excluded, warnings = policy.collect(outcomes)
    if not rows:
        raise policy.nothing_scored(inputs.get("pred"), excluded, extra, expected, warnings)
    missing = {job.stem: job.partner_missing for job in jobs_list if job.partner_missing}
    not_computable = without_partner.not_computable(missing, (row["clip"] for row in rows), suite.PARTNER_KEYS)
    metrics, undefined = _aggregate(rows, {e["clip"] for e in not_computable})
    spread, method = uncertainty.estimate(SUITE, rows, list(suite.KEYS), seed=seed)
    present = {job.stem for job in jobs_list}
    notes = (policy.warning_notes(warnings) + policy.extra_notes(extra, expected)
             + without_partner.notes(not_computable, len(rows), PARTNER_HEADERS)
             + _undefined_notes(undefined, len(rows)))
    if truncated:
        notes.append(f"{len(truncated)} clip(s) truncated to the shortest of prediction, ground truth and "
                     f"partner lengths (listed under coverage.truncated)")
    return ScoreReport(
        suite=SUITE,
        metrics=metrics,
        per_item=rows,
        excluded=excluded,
        coverage={"expected": len(expected), "scored": len(rows),
                  "missing": [s for s in expected if s not in present], "extra": extra,
                  "truncated": truncated, "undefined": undefined, "not_computable": not_computable},
        config=_config(seed, jobs, inputs),
        notes=notes,
        columns=columns(),
        uncertainty=spread,
        uncertainty_method=method,
    )


def _config(seed: int, jobs: int, inputs: dict) -> dict:
    return {
        "suite": SUITE,
        **inputs,
        "seed": seed,
        "diversity_seed_rule": DIVERSITY_SEED_RULE,
        "diversity_times": suite.DIVERSITY_TIMES,
        "sid_k": dict(suite.SID_K),
        "kmeans": 'sklearn.cluster.KMeans(n_clusters=k, random_state=0, n_init="auto")',
        "min_frames": suite.MIN_FRAMES,
        "truncation": "each clip cut to the shortest of prediction, ground truth and partner (when present)",
        "aggregation": "plain mean over clips (a clip whose value is undefined is left out of that "
                       "key's mean and listed under coverage.undefined)",
        "higher_is_better": dict(suite.HIGHER_IS_BETTER),
        "jobs": jobs,
        "threads_per_job": THREADS_PER_JOB,
        "versions": {"numpy": np.__version__, "scipy": scipy.__version__, "scikit-learn": sklearn.__version__},
    }


def score_arrays(items: list[ScoreItem | StoredItem], *, jobs: int = 1, seed: int = 0) -> ScoreReport:
    """Score in-memory predictions: each item's ``pred``, ``gt`` and ``partner`` are (T, 56).

    A :class:`~dyadbench.scoring.stored.StoredItem` is read only in the job that scores it (the same
    numbers as its :class:`ScoreItem` in memory), so a split of them is never held whole.

    ``partner=None`` (its ground truth is missing): the partner-based metrics of that item are not
    computable (listed under ``coverage["not_computable"]``), the others are scored. A wrong shape raises
    :class:`InputError` naming the item; NaN/inf predictions are excluded and listed; length mismatches
    are truncated and counted.
    """
    if not items:
        raise InputError(None, "no items to score")
    stems = [item.stem for item in items]
    duplicated = sorted({s for s in stems if stems.count(s) > 1})
    if duplicated:
        raise InputError(None, f"duplicate item stems: {', '.join(duplicated)}")
    jobs_list = [_item_job(item, derive_seed(seed, item.stem)) for item in items]
    return _run(jobs_list, jobs=jobs, seed=seed, expected=stems, inputs={"pred": "in-memory", "gt": "in-memory"},
                extra=[])


def _item_job(item: ScoreItem | StoredItem, seed: int) -> _Job:
    stored = isinstance(item, StoredItem)
    has_partner = item.has_partner if stored else item.partner is not None
    missing = "" if has_partner else "no partner ground truth given (partner=None)"
    if stored:
        return _Job(item.stem, seed, None, None, None, missing, stored=item)
    return _Job(item.stem, seed, item.pred, item.gt, item.partner, missing)


def partner_stem(stem: str, source: str | None = None) -> str:
    """``<clip>_speaker1`` <-> ``<clip>_speaker2``; other names raise :class:`InputError` (naming
    ``source``, default the stem)."""
    match = AGENT_STEM.match(stem)
    if match is None:
        raise InputError(source or stem, "DualTalk agent names are <clip>_speaker1 or <clip>_speaker2")
    return f"{match['clip']}_speaker{3 - int(match['k'])}"


def ground_truth_stems(gt_dir: Path) -> list[str]:
    """Agent stems with a ground-truth ``.npz`` in a DualTalk split folder (wavs ignored)."""
    if not gt_dir.is_dir():
        raise InputError(gt_dir, "ground truth must be a DualTalk split folder")
    stems = sorted(f.stem for f in gt_dir.glob("*.npz") if AGENT_STEM.match(f.stem))
    if not stems:
        raise InputError(gt_dir, "no DualTalk ground truth (<clip>_speaker1.npz / <clip>_speaker2.npz) here")
    return stems


def score_paths(pred: str | Path, gt: str | Path, *, split: str | None = None, jobs: int = 1,
                seed: int = 0) -> ScoreReport:
    """Score a prediction folder (``<clip>_speakerK.npy``) or ``.npz`` against a DualTalk split folder.

    ``gt`` is the split folder itself, or the DualTalk root when ``split`` names its sub-folder.
    A prediction without its own ground truth is extra (listed, not scored). The partner-based metrics
    also need the partner's ground truth (``_speaker1`` <-> ``_speaker2``); where that file is missing
    (as in the released DualTalk demo clips) they are reported as not computable for that clip, naming
    the file, and every other metric is scored. Coverage is reported against every agent with ground
    truth in the folder.
    """
    gt_dir = Path(gt) / split if split else Path(gt)
    expected = ground_truth_stems(gt_dir)
    predictions = open_predictions(pred)
    known = set(expected)
    extra = [stem for stem in predictions if stem not in known]
    jobs_list = []
    for stem, prediction in predictions.items():
        if stem not in known:
            continue
        partner = gt_dir / f"{partner_stem(stem, prediction.name)}.npz"
        present = partner.name[: -len(".npz")] in known
        jobs_list.append(_Job(stem, derive_seed(seed, stem), prediction, gt_dir / f"{stem}.npz",
                              partner if present else None,
                              "" if present else f"partner ground truth {partner} not found"))
    return _run(jobs_list, jobs=jobs, seed=seed, expected=expected,
                inputs={"pred": str(pred), "gt": str(gt_dir)}, extra=extra)
