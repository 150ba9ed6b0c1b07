"""Score Seamless Interaction predictions (:mod:`dyadbench.metrics.seamless`), from memory or from files.

Scoring is a map over predicted agents (one function per item, :func:`score_item`, which reads its own
files when given paths) and a reduction after (:func:`_report`), so a split of thousands of dyads is
scored file by file in bounded memory, in ``jobs`` processes (:func:`dyadbench.scoring.parallel.map_items`),
and a scheduler could distribute the same items.

Predictions on disk: a folder of ``<stem>.npy`` (or one ``.npz`` keyed by stem), ``stem`` the participant's
file stem ``V.._S.._I.._P..`` and each array (T, D) in the split's layout (166 dims, or 168 with gaze;
the last column is ignored). Bad input follows :mod:`dyadbench.scoring.policy`; a prediction with fewer
than :data:`~dyadbench.metrics.seamless.MIN_FRAMES` frames valid for both participants is excluded with
the reason. Aggregation: the mean over scored agents of each key (undefined values left out and
listed); uncertainty: cluster bootstrap over dyads (:mod:`dyadbench.uncertainty`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from dyadbench import uncertainty
from dyadbench.arrays import check_motion
from dyadbench.datasets.seamless import SEAMLESS, SEAMLESS_GAZE, SeamlessSplit, read_motion
from dyadbench.datasets.seamless_files import Bundle
from dyadbench.errors import InputError
from dyadbench.metrics import seamless as suite
from dyadbench.motion import LAYOUTS
from dyadbench.scoring import policy
from dyadbench.scoring.parallel import map_items
from dyadbench.scoring.predictions import PredictionFile, open_predictions
from dyadbench.scoring.report import ScoreItem, ScoreReport
from dyadbench.seeding import derive_seed

SUITE = "seamless"
LAYOUT_OF_DIM = {SEAMLESS.dim: SEAMLESS.name, SEAMLESS_GAZE.dim: SEAMLESS_GAZE.name}


@dataclass(frozen=True)
class Job:
    """One agent to score: arrays in memory, or where to read them (a prediction file, participant bundles)."""

    stem: str
    seed: int
    layout: str
    pred: np.ndarray | PredictionFile
    gt: np.ndarray | Bundle
    partner: np.ndarray | Bundle


@dataclass
class Outcome:
    stem: str
    metrics: dict[str, float] | None = None
    excluded: str | None = None
    warnings: list[str | None] = field(default_factory=list)


def _motion(value: np.ndarray | Bundle, name: str, layout) -> tuple[np.ndarray, str]:
    if isinstance(value, Bundle):
        return read_motion(value, gaze=layout is SEAMLESS_GAZE), str(value.source)
    return check_motion(value, name, layout.dim), name


def score_item(job: Job) -> Outcome:
    """Read (when given files), check and score one agent. Runs in a worker; errors reach the caller."""
    layout = LAYOUTS[job.layout]
    if isinstance(job.pred, PredictionFile):
        pred, pred_name = job.pred.load(layout.dim), job.pred.name
    else:
        pred_name = f"prediction {job.stem}"
        pred = check_motion(job.pred, pred_name, layout.dim, finite=False)
    gt, gt_name = _motion(job.gt, f"ground truth of {job.stem}", layout)
    partner, partner_name = _motion(job.partner, f"partner ground truth of {job.stem}", layout)
    outcome = Outcome(job.stem, excluded=policy.exclusion(pred, pred_name))
    outcome.warnings = [policy.magnitude_warning(a[:, :-1], name, layout)
                        for a, name in ((gt, gt_name), (partner, partner_name), (pred, pred_name))]
    if outcome.excluded is None:
        try:
            outcome.metrics = suite.item_metrics(pred, gt, partner, layout, seed=job.seed)
        except InputError as exc:
            outcome.excluded = f"{exc.problem} ({pred_name})"
        except ValueError as exc:  # e.g. a Fréchet distance with a large imaginary part
            outcome.excluded = f"could not be scored: {exc}"
    return outcome


def _report(jobs_list: list[Job], *, jobs: int, seed: int, expected: list[str], inputs: dict,
            extra: list[str]) -> ScoreReport:
    layout = LAYOUTS[jobs_list[0].layout]
    keys = suite.keys(layout)
    rows, excluded, warnings = policy.collect(map_items(score_item, jobs_list, jobs=jobs, desc=SUITE))
    if not rows:
        raise policy.nothing_scored(inputs.get("pred"), excluded, extra, expected, warnings)
    metrics, undefined = {}, {}
    for key in keys:
        values = np.array([row[key] for row in rows], dtype=np.float64)
        defined = np.isfinite(values)
        metrics[key] = float(values[defined].mean()) if defined.any() else math.nan
        if not defined.all():
            undefined[key] = [row["clip"] for row, ok in zip(rows, defined) if not ok]
    spread, method = uncertainty.estimate(SUITE, rows, keys, seed=seed, unavailable=suite.NOT_COMPUTED)
    present = {job.stem for job in jobs_list}
    frames_excluded = int(sum(row["frames_excluded"] for row in rows))
    notes = (policy.warning_notes(warnings) + policy.extra_notes(extra, expected)
             + [f"{key} undefined for {len(c)} of {len(rows)} agents; its mean is over the others"
                for key, c in undefined.items()]
             + [f"{frames_excluded} frame(s) with invalid movement features (agent or partner) excluded from every "
                f"metric ({int(sum(row['frames_scored'] for row in rows))} scored)"]
             + [f"{name} not computed: {why}" for name, why in suite.NOT_COMPUTED.items()])
    return ScoreReport(
        suite=SUITE, metrics=metrics, per_item=rows, excluded=excluded,
        coverage={"expected": len(expected), "scored": len(rows), "missing": [s for s in expected if s not in present],
                  "extra": extra, "undefined": undefined, "frames_excluded": frames_excluded},
        config={"suite": SUITE, **inputs, "layout": layout.name, "seed": seed, "jobs": jobs,
                "scored_frames": "frames whose movement features are valid for agent and partner (is_valid = 1)",
                "sid_k": dict(suite.SID_K), "min_frames": suite.MIN_FRAMES,
                "emotion_dtw_groups": [list(g) for g in suite.EMOTION_GROUPS],
                "higher_is_better": suite.COLUMNS.directions(keys), "not_computed": dict(suite.NOT_COMPUTED)},
        notes=notes, columns=suite.COLUMNS.table_columns(set(keys)), uncertainty=spread, uncertainty_method=method)


def score_arrays(items: list[ScoreItem], *, jobs: int = 1, seed: int = 0) -> ScoreReport:
    """Score in-memory agents: ``pred``, ``gt`` and ``partner`` (T, D) in the ``seamless`` (D = 166) or
    ``seamless-gaze`` (168) layout, all items alike."""
    if not items:
        raise InputError(None, "no items to score")
    dims = {np.shape(item.gt)[-1] for item in items}
    if len(dims) != 1 or next(iter(dims)) not in LAYOUT_OF_DIM:
        raise InputError(None, f"ground truth must be (T, {' or '.join(map(str, LAYOUT_OF_DIM))}) for every item, "
                               f"got widths {sorted(dims)}")
    layout = LAYOUT_OF_DIM[dims.pop()]
    for item in items:
        if item.partner is None:
            raise InputError(item.stem, "the seamless suite needs the partner's ground truth (partner=None)")
    jobs_list = [Job(item.stem, derive_seed(seed, item.stem), layout, item.pred, item.gt, item.partner)
                 for item in items]
    return _report(jobs_list, jobs=jobs, seed=seed, expected=[i.stem for i in items],
                   inputs={"pred": "in-memory", "gt": "in-memory"}, extra=[])


def split_jobs(data: SeamlessSplit, predictions: dict[str, PredictionFile], seed: int,
               layout: str = SEAMLESS.name) -> tuple[list[Job], list[str], list[str]]:
    """(jobs, expected stems, extra stems): one job per usable participant with a prediction."""
    jobs_list, expected = [], []
    for first, second in data.pairs.values():
        for agent, partner in ((first, second), (second, first)):
            expected.append(agent.stem)
            if agent.stem in predictions:
                jobs_list.append(Job(agent.stem, derive_seed(seed, agent.stem), layout, predictions[agent.stem],
                                     agent, partner))
    known = set(expected)
    return jobs_list, expected, [s for s in predictions if s not in known]


def score_paths(pred: str | Path, gt: str | Path, *, split: str | None = None, jobs: int = 1,
                seed: int = 0) -> ScoreReport:
    """Score a prediction folder (``<participant stem>.npy``) or ``.npz`` against a Seamless root ``gt``,
    split ``split`` (``test`` or ``<label>/test``; None: test). Skipped dyads are named in the notes."""
    data = SeamlessSplit.open(gt, split or "test")
    predictions = open_predictions(pred)
    jobs_list, expected, extra = split_jobs(data, predictions, seed)
    if not jobs_list:
        raise policy.nothing_scored(pred, [], extra, expected)
    report = _report(jobs_list, jobs=jobs, seed=seed, expected=expected,
                     inputs={"pred": str(pred), "gt": str(gt), "split": data.split}, extra=extra)
    if data.skipped:
        report.notes.append(f"{data.skipped_dyads()} dyad(s) of the split skipped (empty bundles, no movement "
                            f"features or not two usable participants): {'; '.join(s['reason'] for s in data.skipped[:3])}")
    return report
