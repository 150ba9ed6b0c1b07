"""Fitting baselines on a train split, with fitted statistics cached by the split's digest.

:func:`cached_fit` stores what a baseline fitted as ``<cache>/baselines/<kind>-v<version>-<key>.npz``
(key: :func:`dyadbench.provenance.source_key` of the train split, from its files' paths, sizes and
modification times) and reuses it while the split is unchanged. :func:`frame_statistics` computes the
statistics of the trivial baselines over every valid frame of every participant of the split.

**Valid frames.** A motion layout may declare a validity column, the component ``valid`` (the Seamless
Interaction layout's ``movement:is_valid``, 0 on the zero-filled frames the corpus could not track). Fits
use only the frames where it is 1 (:func:`valid_frames`), so untracked frames never pull fitted statistics
toward zero; layouts without it (FLAME, gaze) use every frame.
"""

from __future__ import annotations

import hashlib
import math
from typing import Callable

import numpy as np
from tqdm import tqdm

from dyadbench import atomic
from dyadbench.datasets.base import ClipSource
from dyadbench.errors import InputError
from dyadbench.motion import LAYOUTS
from dyadbench.paths import cache_dir
from dyadbench.provenance import source_key
from dyadbench.protocol.train_split import open_for

MEDIAN_MAX_FRAMES = 200_000  # the median is taken over every k-th frame, k chosen to keep at most this many
STATS_VERSION = 2  # version of frame_statistics' cached arrays (2: frames a layout marks invalid left out)


def open_train(train_split: Callable[[], ClipSource] | None, model: str) -> ClipSource:
    """The train split of a baseline's options, or a ConfigError (naming the baseline) saying it needs one
    or why it cannot have it (:class:`dyadbench.protocol.train_split.TrainSplit`)."""
    source = open_for(train_split, model, missing="is fitted on a train split; pass ModelOptions(train_split=...)")
    if len(source) == 0:
        raise InputError(f"{source.dataset}/{source.split}", f"{model}: the train split has no clips")
    return source


def cached_fit(kind: str, version: int, source: ClipSource,
               fit: Callable[[ClipSource], dict[str, np.ndarray]]) -> tuple[dict[str, np.ndarray], str]:
    """``fit(source)`` cached on disk; returns (arrays, sha256 of the cached file)."""
    path = cache_dir() / "baselines" / f"{kind}-v{version}-{source_key(source)[:20]}.npz"
    if not path.is_file():
        atomic.save_npz(path, **fit(source))
    with np.load(path) as data:
        arrays = {k: data[k] for k in data.files}
    return arrays, hashlib.sha256(path.read_bytes()).hexdigest()


def valid_frames(motion: np.ndarray, layout: str) -> np.ndarray:
    """(T,) bool: the frames a fit may use: those whose ``valid`` column of ``layout`` is 1 (> 0.5), or every
    frame when the layout declares no validity column."""
    cols = LAYOUTS[layout].components.get("valid")
    motion = np.asarray(motion)
    if cols is None:
        return np.ones(motion.shape[0], dtype=bool)
    return motion[:, cols].reshape(motion.shape[0], -1)[:, 0] > 0.5


def frame_statistics(source: ClipSource) -> dict[str, np.ndarray]:
    """Mean, covariance (ddof=1) and median of the valid frames (:func:`valid_frames`) of all participants
    of ``source``; ``frames`` counts the frames used.

    Mean and covariance are exact (float64 running sums). The median is the per-dimension median of
    every k-th frame of each participant, k = ceil(estimated frames / MEDIAN_MAX_FRAMES) (k = 1 for
    splits of up to 200,000 frames), so memory stays bounded on DualTalk-sized splits.
    """
    ids = source.clip_ids()
    stride = None
    total = 0
    sums = sumsq = None
    kept: list[np.ndarray] = []
    for clip_id in tqdm(ids, desc=f"fitting on {source.dataset}/{source.split}", unit="clip", leave=False):
        clip = source.load(clip_id)
        for p in clip.participants:
            m = np.asarray(p.motion, dtype=np.float64)
            if stride is None:
                estimate = len(ids) * len(clip.participants) * max(m.shape[0], 1)
                stride = max(1, math.ceil(estimate / MEDIAN_MAX_FRAMES))
                sums = np.zeros(m.shape[1])
                sumsq = np.zeros((m.shape[1], m.shape[1]))
            if m.shape[1] != sums.shape[0]:
                raise InputError(f"{clip.clip_id}_{p.name}", f"motion has {m.shape[1]} dims, "
                                                            f"other clips of the split have {sums.shape[0]}")
            m = m[valid_frames(m, clip.layout)]
            total += m.shape[0]
            sums += m.sum(axis=0)
            sumsq += m.T @ m
            kept.append(m[::stride].astype(np.float32))
    if total < 2:
        raise InputError(f"{source.dataset}/{source.split}", "fewer than 2 valid frames in the train split")
    mean = sums / total
    cov = (sumsq - total * np.outer(mean, mean)) / (total - 1)
    return {"mean": mean, "cov": (cov + cov.T) / 2, "median": np.median(np.concatenate(kept), axis=0),
            "frames": np.array(total), "median_stride": np.array(stride)}
