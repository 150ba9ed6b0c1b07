"""Fit the headroom estimator for n = 0 … 7 on one corpus and score it on its evaluation splits.

For each n the estimator is the ridge regression of :mod:`dyadbench.headroom.ridge` on the first
``columns(n)`` columns of the rows of :mod:`dyadbench.headroom.features` (same current-turn block for every
n, one weight block per history distance d = 1 … n), fitted on the train clips, its penalty chosen per
component on the validation clips, and scored on each evaluation split with :mod:`dyadbench.headroom.scores`.
Both directions of every clip are used (each participant once the agent). Clips are the first ``N`` of
each split's sorted ids. Nothing is random except the bootstrap of the relative change, which is seeded.

The relative change at n is mean_n / mean_0 − 1 of a scaled metric; its 95 % interval resamples the
dialogues (both directions of a clip together) with ``numpy.random.default_rng(seed)``, the same resamples
for every n and metric (:data:`RESAMPLES`).
"""

from __future__ import annotations

from typing import Callable, Iterator

import numpy as np
from tqdm import tqdm

from dyadbench.datasets.base import ClipSource
from dyadbench.errors import InputError
from dyadbench.headroom.features import MAX_CONTEXT, Direction, columns, direction_features
from dyadbench.headroom.ridge import Moments, RidgeFit, fit
from dyadbench.headroom.scores import KEYS, prediction_scores, scaled_means
from dyadbench.provenance import split_digest

CONTEXTS = tuple(range(MAX_CONTEXT + 1))
RESAMPLES = 1000


def directions(source: ClipSource, clips: int, progress: bool = False) -> Iterator[tuple[str, Direction]]:
    """(clip id, features) of every evaluated direction of the first ``clips`` clips of ``source``."""
    ids = source.clip_ids()[:clips]
    if len(ids) < clips:
        raise InputError(f"{source.dataset}/{source.split}", f"has {len(ids)} clips, {clips} requested")
    for clip_id in tqdm(ids, desc=f"headroom {source.dataset}/{source.split}", unit="clip", disable=not progress,
                        leave=False):
        clip = source.load(clip_id)
        for p in clip.agent_participants:
            yield clip_id, direction_features(clip, p.name)


def moments(source: ClipSource, clips: int, progress: bool = False) -> Moments:
    """Moments (:class:`~dyadbench.headroom.ridge.Moments`) of the rows for n = 7 of ``clips`` clips."""
    total = Moments()
    for _, d in directions(source, clips, progress):
        total.add(d.rows, d.target)
    return total


def fit_contexts(train: Moments, val: Moments) -> dict[int, RidgeFit]:
    """One ridge fit per n in :data:`CONTEXTS` (the first ``columns(n)`` columns of the moments)."""
    return {n: fit(train.head(columns(n)), val.head(columns(n)), history_from=columns(0)) for n in CONTEXTS}


def score_split(fits: dict[int, RidgeFit], source: ClipSource, clips: int, *, seed: int,
                progress: bool = False) -> dict:
    """Scaled means per n, and each n's relative change against n = 0 with its bootstrap interval."""
    groups: list[str] = []
    rows: dict[int, list[dict[str, float]]] = {n: [] for n in fits}
    for clip_id, d in directions(source, clips, progress):
        groups.append(clip_id)
        for n, f in fits.items():
            pred = d.rows[:, :columns(n)] @ f.weights
            rows[n].append(prediction_scores(pred, d.target, d.partner))
    means = {str(n): scaled_means(r) for n, r in rows.items()}
    change = relative_change(rows, groups, seed)
    return {"predictions": len(groups), "dialogues": len(set(groups)), "means": means, "change": change}


def relative_change(rows: dict[int, list[dict[str, float]]], groups: list[str], seed: int) -> dict:
    """{n: {key: [change, low, high]}} of mean_n / mean_0 − 1 (see the module docstring)."""
    names = sorted(set(groups))
    index = np.array([names.index(g) for g in groups])
    members = [np.flatnonzero(index == i) for i in range(len(names))]
    draws = np.random.default_rng(seed).integers(0, len(names), size=(RESAMPLES, len(names)))
    picks = [np.concatenate([members[i] for i in draw]) for draw in draws]
    out = {}
    for n in rows:
        out[str(n)] = {}
        for k in KEYS:
            base = np.array([r[k] for r in rows[0]])
            value = np.array([r[k] for r in rows[n]])
            boot = [value[p].mean() / base[p].mean() - 1.0 for p in picks]
            low, high = np.percentile(boot, [2.5, 97.5])
            out[str(n)][k] = [float(value.mean() / base.mean() - 1.0), float(low), float(high)]
    return out


def measure(open_split: Callable[[str], ClipSource], clips: dict[str, int], *, eval_splits: tuple[str, ...],
            seed: int = 0, progress: bool = False) -> dict:
    """The headroom of one corpus: fit on ``clips['train']`` train and ``clips['val']`` val clips, score on
    ``clips[split]`` clips of each of ``eval_splits``. ``open_split(split)`` opens a split of the corpus. Each
    split's data is recorded as eval results record it: the digest of the clips used
    (:func:`dyadbench.provenance.split_digest`) and, for a generated corpus, its generator's identity."""
    sources = {s: open_split(s) for s in ("train", "val", *eval_splits)}
    train = moments(sources["train"], clips["train"], progress)
    val = moments(sources["val"], clips["val"], progress)
    fits = fit_contexts(train, val)
    return {
        "clips": {s: clips[s] for s in sources},
        "data": {s: {"digest": split_digest(source, source.clip_ids()[:clips[s]]),
                     "generated_by": source.generated_by()} for s, source in sources.items()},
        "rows": {"train": train.n, "val": val.n},
        "fit": {str(n): {"penalty": f.penalty, "history_ratio": f.history_ratio, "val_mse": f.val_mse}
                for n, f in fits.items()},
        "splits": {s: score_split(fits, sources[s], clips[s], seed=seed, progress=progress) for s in eval_splits},
    }
