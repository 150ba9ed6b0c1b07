"""Score REACT predictions (25-d emotion features, R reactions per speaker sample) from memory or disk.

Predictions on disk (``score_paths``), for the N = 2M samples of a split in REACT's mirrored order:

- an ``.npz`` holding ``predictions`` (N, R, T, 25) in that order; or
- an ``.npz`` (or a folder of ``.npy`` files) with one (R, T, 25) array per sample, named by the
  sample's *speaker* relative path from the split csv: key ``NoXI/<session>/Expert_video/3`` (a
  folder: file ``<folder>/NoXI/<session>/Expert_video/3.npy``). Every person is the speaker of exactly
  one sample, so the names are unique; a name without a sample (or a sample without a prediction) is
  an error that names it.

Like the official evaluation, every clip is cut to its first :data:`~dyadbench.metrics.react.FRAMES`
(750) frames; predictions need at least that many, and exactly R = 10 reactions. Scoring needs every
sample (FRDvs and the neighbour matrix couple them), so nothing is excluded: a NaN is an error.
"""

from __future__ import annotations

import zipfile
from pathlib import Path

import numba
import numpy as np
import tslearn

from dyadbench.arrays import load_npy, load_npz
from dyadbench.datasets.react import SCORED_SPLITS, ReactSplit, neighbour_path
from dyadbench.errors import InputError
from dyadbench.metrics import react as suite
from dyadbench.metrics.tlcc import MAX_LAG
from dyadbench.scoring.report import Column, ScoreItem, ScoreReport

SUITE = "react"
STACKED_KEY = "predictions"
PER_SAMPLE_KEYS = ("FRCorr", "FRDist", "FRDiv", "FRVar", "FRSyn")


def columns() -> list[Column]:
    arrows = {True: "↑", False: "↓"}
    return [Column(m.name, f"{m.name}{arrows[m.higher_is_better]}") for m in suite.METRICS]


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
        "higher_is_better": dict(suite.HIGHER_IS_BETTER),
        "not_computed": dict(suite.NOT_COMPUTED),
        "threads": jobs,
        "versions": {"numpy": np.__version__, "numba": numba.__version__, "tslearn": tslearn.__version__},
    }


def _report(stems: list[str], predictions, listener, speaker, neighbours, *, jobs: int, seed: int,
            inputs: dict, notes: list[str], reactions: int | None = suite.REACTIONS) -> ScoreReport:
    previous = numba.get_num_threads()
    numba.set_num_threads(max(1, min(jobs, numba.config.NUMBA_NUM_THREADS)))
    try:
        metrics, per_sample = suite.evaluate(predictions, listener, speaker, neighbours, reactions=reactions,
                                             progress=True)
    finally:
        numba.set_num_threads(previous)
    rows = [{"clip": stem, **{k: float(per_sample[k][i]) for k in PER_SAMPLE_KEYS}} for i, stem in enumerate(stems)]
    notes = list(notes) + [f"{name} not computed: {why}" for name, why in suite.NOT_COMPUTED.items()]
    return ScoreReport(suite=SUITE, metrics=metrics, scaled=dict(metrics), per_item=rows,
                       coverage={"expected": len(stems), "scored": len(stems), "missing": [], "extra": []},
                       config=_config(inputs, seed, jobs, np.shape(predictions)[1], np.shape(predictions)[2],
                                      neighbours),
                       notes=notes, columns=columns())


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
    preds = [np.asarray(item.pred) for item in items]
    shapes = {p.shape for p in preds}
    if len(shapes) != 1:
        raise InputError(items[0].stem, f"predictions differ in shape: {sorted(shapes)}")
    return _report([i.stem for i in items], np.stack(preds), np.stack([i.gt for i in items]),
                   np.stack([i.partner for i in items]), neighbours, jobs=jobs, seed=seed,
                   inputs={"pred": "in-memory", "gt": "in-memory"}, notes=notes, reactions=None)


def _npz_keys(path: Path) -> list[str]:
    try:
        with zipfile.ZipFile(path) as archive:
            return [n[: -len(".npy")] for n in archive.namelist() if n.endswith(".npy")]
    except (zipfile.BadZipFile, OSError) as exc:
        raise InputError(path, f"unreadable .npz archive ({exc})") from None


def _cut(array: np.ndarray, name: str, shape_tail: tuple[int, ...], frames: int) -> np.ndarray:
    """Check (..., T, 25) with T >= frames and the expected leading dims; keep the first ``frames``."""
    if array.ndim != len(shape_tail) + 2 or array.shape[-1] != suite.DIM or array.shape[:-2] != shape_tail:
        want = "(" + ", ".join(str(s) for s in shape_tail + ("T",)) + f", {suite.DIM})"
        raise InputError(name, f"expected shape {want}, got {array.shape}")
    if array.shape[-2] < frames:
        raise InputError(name, f"has {array.shape[-2]} frames; the evaluation uses the first {frames}")
    if array.dtype.kind not in "fiu":
        raise InputError(name, f"expected real numbers, got dtype {array.dtype}")
    return array[..., :frames, :]


class _KeyedPredictions:
    """One (R, T, 25) array per speaker path: the members of an ``.npz`` or the ``.npy`` files of a folder."""

    def __init__(self, pred: Path, keys: list[str] | None = None):
        self.pred = pred
        self.archive = keys is not None
        if self.archive:
            self.keys = set(keys)
        else:
            self.keys = {f.relative_to(pred).with_suffix("").as_posix() for f in pred.rglob("*.npy")}

    def name(self, key: str) -> str:
        return f"{self.pred}[{key}]" if self.archive else str(self.pred / f"{key}.npy")

    def load(self, key: str) -> np.ndarray:
        return load_npz(self.pred, [key])[key] if self.archive else load_npy(self.pred / f"{key}.npy")


def load_predictions(pred: Path, speakers: list[str], reactions: int, frames: int) -> np.ndarray:
    """(N, R, frames, 25) float32 in sample order from any of the accepted prediction forms."""
    n = len(speakers)
    if pred.is_file() and pred.suffix == ".npz":
        keys = _npz_keys(pred)
        if STACKED_KEY in keys:
            array = load_npz(pred, [STACKED_KEY])[STACKED_KEY]
            return _cut(array, f"{pred}[{STACKED_KEY}]", (n, reactions), frames).astype(np.float32)
        found = _KeyedPredictions(pred, keys)
    elif pred.is_dir():
        found = _KeyedPredictions(pred)
    else:
        raise InputError(pred, "predictions must be an .npz or a folder of .npy files")
    missing = [s for s in speakers if s not in found.keys]
    extra = sorted(found.keys - set(speakers))
    if missing or extra:
        problems = []
        if missing:
            problems.append(f"{len(missing)} sample(s) without a prediction (e.g. {missing[0]})")
        if extra:
            problems.append(f"{len(extra)} name(s) that are no sample's speaker path (e.g. {extra[0]})")
        raise InputError(pred, "; ".join(problems) + f"; expected the key {STACKED_KEY!r} with (N, R, T, 25) "
                               "or one (R, T, 25) array per speaker relative path")
    out = np.empty((n, reactions, frames, suite.DIM), dtype=np.float32)
    for k, speaker in enumerate(speakers):
        out[k] = _cut(found.load(speaker), found.name(speaker), (reactions,), frames)
    return out


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
    predictions = load_predictions(Path(pred), speakers, suite.REACTIONS, suite.FRAMES)
    return _report(speakers, predictions, listener, speaker, neighbours, jobs=jobs, seed=seed,
                   inputs={"pred": str(pred), "gt": str(root), "split": split,
                           "neighbours": str(neighbour_path(root, split))}, notes=[])
