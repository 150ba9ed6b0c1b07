"""Score REACT predictions (25-d emotion features, R reactions per speaker sample) from memory or disk.

Predictions on disk (``score_paths``), for the N = 2M samples of a split in REACT's mirrored order:

- an ``.npz`` holding ``predictions`` (N, R, T, 25) in that order; or
- an ``.npz`` (or a folder of ``.npy`` files) with one (R, T, 25) array per sample, named by the
  sample's *speaker* relative path from the split csv: key ``NoXI/<session>/Expert_video/3`` (a
  folder: file ``<folder>/NoXI/<session>/Expert_video/3.npy``). Every person is the speaker of exactly
  one sample, so the names are unique.

Like the official evaluation, every clip is cut to its first :data:`~dyadbench.metrics.react.FRAMES`
(750) frames and every array is held as float32; predictions need exactly R = 10 reactions. Bad input
follows the policy of every suite (:mod:`dyadbench.scoring.policy`): a sample whose prediction holds
NaN/inf (after the float32 rounding) or has fewer than 750 frames is excluded and listed, a sample
without a prediction is listed as missing, a name that is no sample's speaker path as extra. The
metrics are computed over the scored samples, each against the full pool of real listener reactions
(the neighbour matrix's rows of the scored samples, all its columns); FRDvs pairs the scored samples.
Uncertainty (:mod:`dyadbench.uncertainty`): every column but FRDvs is a mean over samples and gets a
standard error and a bootstrap CI resampling sessions (both roles and every segment of a session
together); FRDvs has none (:data:`NO_UNCERTAINTY`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numba
import numpy as np
import tslearn

from dyadbench import uncertainty
from dyadbench.arrays import require_float, shape_problem
from dyadbench.datasets.react import REACT25, SCORED_SPLITS, ReactSplit, neighbour_path
from dyadbench.errors import InputError
from dyadbench.metrics import react as suite
from dyadbench.metrics.columns import ColumnSpec
from dyadbench.metrics.tlcc import MAX_LAG
from dyadbench.scoring import policy
from dyadbench.scoring.predictions import open_predictions
from dyadbench.scoring.report import ScoreItem, ScoreReport

SUITE = "react"
STACKED_KEY = "predictions"
PER_SAMPLE_KEYS = ("FRCorr", "FRDist", "FRDiv", "FRVar", "FRSyn")
#: Columns without an uncertainty, and why (the others are means over samples, resampled by session).
NO_UNCERTAINTY = {"FRDvs": "diversity across speaker samples: a bootstrap resample repeats samples, whose "
                           "zero-distance pairs bias it, so no resampled interval is given"}


def columns() -> list[ColumnSpec]:
    """The declared columns (:data:`dyadbench.metrics.react.COLUMNS`)."""
    return list(suite.COLUMNS.columns)


def _config(inputs: dict, seed: int, jobs: int, reactions: int, frames: int, neighbours: np.ndarray) -> dict:
    counts = (np.asarray(neighbours) == 1).sum(axis=1)
    return {
        "suite": SUITE, **inputs, "seed": seed, "randomness": "none (the suite is deterministic)",
        "reactions": reactions, "frames": frames, "dims": suite.DIM,
        "precision": "inputs rounded to float32 (as the official loader holds them), arithmetic in float64",
        "frdist_groups": [list(g) for g in suite.DTW_GROUPS],
        "dtw": "exact (tslearn dtw: squared Euclidean local cost, no window, full grid); minimum over neighbours "
               "via a certified float32 screen, recomputed in float64 (same values)",
        "frsyn": f"reaction 0 only (official); FRSyn_all averages all reactions; lags -{MAX_LAG}..{MAX_LAG}",
        "neighbours_per_row": {"mean": float(counts.mean()), "min": int(counts.min()), "max": int(counts.max())},
        "higher_is_better": suite.COLUMNS.directions(suite.KEYS),
        "not_computed": dict(suite.NOT_COMPUTED),
        "threads": jobs,
        "versions": {"numpy": np.__version__, "numba": numba.__version__, "tslearn": tslearn.__version__},
    }


def _report(stems: list[str], found: SamplePredictions, listener: np.ndarray, speaker: np.ndarray,
            neighbours: np.ndarray, *, jobs: int, seed: int, inputs: dict, notes: list[str],
            gt_names: list[tuple[str, str]], reactions: int | None = suite.REACTIONS) -> ScoreReport:
    """Score the samples of ``found`` (the others are excluded, missing or extra) against every sample's
    ground truth; ``gt_names`` names each sample's (listener, speaker) ground truth in warnings."""
    warnings = found.warnings + [policy.magnitude_warning(array[k], names[i], REACT25)
                                 for k, names in enumerate(gt_names) for i, array in enumerate((listener, speaker))]
    keep = [k for k, stem in enumerate(stems) if stem in found.arrays]
    if not keep:
        raise policy.nothing_scored(inputs.get("pred"), found.excluded, found.extra, stems, warnings)
    predictions = np.stack([found.arrays[stems[k]] for k in keep])
    previous = numba.get_num_threads()
    numba.set_num_threads(max(1, min(jobs, numba.config.NUMBA_NUM_THREADS)))
    try:
        metrics, per_sample = suite.evaluate(predictions, listener, speaker[keep], np.asarray(neighbours)[keep],
                                             reactions=reactions, progress=True)
    finally:
        numba.set_num_threads(previous)
    rows = [{"clip": stems[k], **{key: float(per_sample[key][i]) for key in PER_SAMPLE_KEYS}}
            for i, k in enumerate(keep)]
    spread, method = uncertainty.estimate(
        SUITE, [{**row, "FRSyn_all": float(per_sample["FRSyn_all"][i])} for i, row in enumerate(rows)],
        [*PER_SAMPLE_KEYS, "FRSyn_all"], seed=seed, unavailable=NO_UNCERTAINTY)
    notes = (policy.warning_notes(warnings) + policy.extra_notes(found.extra, stems) + list(notes)
             + [f"{name} not computed: {why}" for name, why in suite.NOT_COMPUTED.items()])
    return ScoreReport(suite=SUITE, metrics=metrics, per_item=rows, excluded=found.excluded,
                       coverage={"expected": len(stems), "scored": len(keep), "missing": found.missing,
                                 "extra": found.extra},
                       config=_config(inputs, seed, jobs, predictions.shape[1], predictions.shape[2], neighbours),
                       notes=notes, columns=columns(), uncertainty=spread, uncertainty_method=method)


@dataclass
class SamplePredictions:
    """The predictions found for a split's samples: the scorable ones (``arrays``: speaker path ->
    (R, T, 25) float32) and, following :mod:`dyadbench.scoring.policy`, the excluded ones (with their
    reasons), the missing and the extra names, and the magnitude warnings."""

    arrays: dict[str, np.ndarray] = field(default_factory=dict)
    excluded: list[dict] = field(default_factory=list)
    missing: list[str] = field(default_factory=list)
    extra: list[str] = field(default_factory=list)
    warnings: list[str | None] = field(default_factory=list)

    def add(self, stem: str, array: np.ndarray, name: str, reactions: int | None, frames: int | None) -> None:
        """Check one sample's prediction (shape and dtype: errors; then the exclusion rules) and keep it
        as float32, cut to ``frames`` (None: all). ``reactions`` None accepts any R."""
        array = np.asarray(array)
        expected = (reactions or "R", "T", suite.DIM)
        if array.ndim != 3 or array.shape[-1] != suite.DIM or array.shape[0] != (reactions or array.shape[0]):
            raise InputError(name, shape_problem(array.shape, "(" + ", ".join(map(str, expected)) + ")",
                                                 transposed=array.ndim == 3 and array.shape[1] == suite.DIM))
        require_float(array, name)
        array = array.astype(np.float32)  # the official loader's precision (values beyond its range are inf)
        reason = policy.exclusion(array, name)
        if reason is None and frames is not None and array.shape[1] < frames:
            reason = policy.too_short(name, array.shape[1], frames)
        if reason is not None:
            self.excluded.append({"clip": stem, "reason": reason})
            return
        self.warnings.append(policy.magnitude_warning(array, name, REACT25))
        self.arrays[stem] = array[:, :frames] if frames is not None else array


def score_arrays(items: list[ScoreItem], *, neighbours: np.ndarray | None = None, jobs: int = 1,
                 seed: int = 0) -> ScoreReport:
    """Score in-memory samples: ``item.pred`` (R, T, 25), ``item.gt`` the listener (T, 25) and
    ``item.partner`` the speaker (T, 25), in the order of ``neighbours`` (N, N).

    Without ``neighbours`` each sample's only appropriate reaction is its own listener (identity matrix;
    said in the notes). Any R is accepted here (all items must agree).
    """
    if not items:
        raise InputError(None, "no items to score")
    for item in items:
        if item.partner is None:
            raise InputError(item.stem, "the REACT suite needs the speaker's features (partner=None)")
    notes = []
    if neighbours is None:
        neighbours = np.eye(len(items), dtype=np.int64)
        notes.append("no neighbour matrix given: each sample's own listener is its only appropriate reaction")
    shapes = {np.shape(item.pred) for item in items}
    if len(shapes) != 1:
        raise InputError(items[0].stem, f"predictions differ in shape: {sorted(shapes)}")
    found = SamplePredictions()
    for item in items:
        found.add(item.stem, item.pred, item.pred_name, None, None)
    gt_names = [(item.gt_name, f"speaker of {item.stem}") for item in items]
    listener, speaker = ([np.asarray(getattr(item, role)) for item in items] for role in ("gt", "partner"))
    for arrays, i in ((listener, 0), (speaker, 1)):
        for array, names in zip(arrays, gt_names):
            require_float(array, names[i])
            policy.check_ground_truth(array, names[i])
    return _report([i.stem for i in items], found, np.stack(listener), np.stack(speaker), neighbours, jobs=jobs,
                   seed=seed, inputs={"pred": "in-memory", "gt": "in-memory"}, notes=notes, gt_names=gt_names,
                   reactions=None)


def load_predictions(pred: Path, speakers: list[str], reactions: int, frames: int) -> SamplePredictions:
    """The predictions of the samples (named by their speaker paths) from any accepted form, checked
    and cut to ``frames``; see :class:`SamplePredictions`."""
    found = SamplePredictions()
    files = open_predictions(pred, recursive=True)
    stacked = files.pop(STACKED_KEY, None) if pred.is_file() else None
    if stacked is not None:
        array = stacked.read()
        if array.ndim != 4 or array.shape[:2] != (len(speakers), reactions) or array.shape[-1] != suite.DIM:
            raise InputError(stacked.name, shape_problem(array.shape, f"({len(speakers)}, {reactions}, T, "
                                                                      f"{suite.DIM})"))
        for k, speaker in enumerate(speakers):
            found.add(speaker, array[k], f"{stacked.name}[{k}] (sample {speaker})", reactions, frames)
        found.extra = sorted(files)
        return found
    for speaker in speakers:
        if speaker in files:
            found.add(speaker, files[speaker].read(), files[speaker].name, reactions, frames)
        else:
            found.missing.append(speaker)
    found.extra = sorted(set(files) - set(speakers))
    return found


def _default_split(root: Path) -> str:
    for split in SCORED_SPLITS:
        if (root / f"{split}.csv").is_file() and neighbour_path(root, split).is_file():
            return split
    raise InputError(root, "no scorable split: need val.csv + neighbour_emotion_val.npy or the test pair")


def score_paths(pred: str | Path, gt: str | Path, *, split: str | None = None, jobs: int = 1,
                seed: int = 0) -> ScoreReport:
    """Score predictions (see the module docstring) against the REACT root ``gt``, split val or test
    (default: val when present). ``jobs`` = threads for the per-pair work (FRDist, FRCorr, FRSyn)."""
    root = Path(gt)
    split = split or _default_split(root)
    if split not in SCORED_SPLITS:
        raise InputError(root, f"REACT scores the val and test splits (they have neighbour matrices), not {split!r}")
    data = ReactSplit.open(root, split)
    neighbours = data.neighbours()
    listener, speaker = data.ground_truth(suite.FRAMES, progress=True)
    speakers = [s for s, _ in data.samples]
    found = load_predictions(Path(pred), speakers, suite.REACTIONS, suite.FRAMES)
    gt_names = [(str(data.emotion_path(lst)), str(data.emotion_path(spk))) for spk, lst in data.samples]
    return _report(speakers, found, listener, speaker, neighbours, jobs=jobs, seed=seed,
                   inputs={"pred": str(pred), "gt": str(root), "split": split,
                           "neighbours": str(neighbour_path(root, split))}, notes=[], gt_names=gt_names)
