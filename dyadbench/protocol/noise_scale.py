"""The motion-noise scale of the robustness protocol, from the train split (TIMAR's released rule).

sigma = round(mean over the D motion dimensions of std_d, 3), where std_d is the standard deviation of
dimension d over every frame of every participant of the train split (population std; the release reads
it from the training statistics file, ``stat_flame.json``). It is cached by the split's file key
(:func:`dyadbench.provenance.source_key`) as ``<cache>/perturbations/motion-std-<key>.json``.
:func:`resolve_noise_scale` fills it into a protocol configuration that needs it; a split without a train
split (a single split folder) must be given the scale (``--noise-scale``).
"""

from __future__ import annotations

import json
from dataclasses import replace
from typing import Callable

import numpy as np

from dyadbench import atomic
from dyadbench.datasets.base import ClipSource
from dyadbench.errors import InputError
from dyadbench.paths import cache_dir
from dyadbench.protocol.config import ProtocolConfig
from dyadbench.protocol.perturbations import needs_noise_scale
from dyadbench.provenance import source_key
from dyadbench.protocol.train_split import open_for

DECIMALS = 3  # the release rounds the scale to 3 decimals


def motion_std(source: ClipSource) -> np.ndarray:
    """Per-dimension population std over every frame of every participant of ``source`` (float64 sums)."""
    total, sums, sumsq = 0, 0.0, 0.0
    for clip in source:
        for person in clip.participants:
            m = np.asarray(person.motion, dtype=np.float64)
            total += m.shape[0]
            sums = sums + m.sum(axis=0)
            sumsq = sumsq + np.square(m).sum(axis=0)
    if total == 0:
        raise InputError(f"{source.dataset}/{source.split}", "no motion frames to take the noise scale from")
    mean = sums / total
    return np.sqrt(np.maximum(sumsq / total - mean ** 2, 0.0))


def train_noise_scale(source: ClipSource) -> float:
    """round(mean(:func:`motion_std`), 3), cached by the split's file key."""
    path = cache_dir() / "perturbations" / f"motion-std-{source_key(source)[:20]}.json"
    if not path.is_file():
        atomic.write_json(path, {"dataset": source.dataset, "split": source.split,
                                 "std": motion_std(source).tolist()})
    std = json.loads(path.read_text(encoding="utf-8"))["std"]
    return round(float(np.mean(std)), DECIMALS)


def resolve_noise_scale(config: ProtocolConfig, train_split: Callable[[], ClipSource] | None) -> ProtocolConfig:
    """``config`` with ``noise_scale`` taken from the train split when a motion-noise perturbation needs one
    and none was given; a ConfigError saying to pass ``--noise-scale`` when there is no train split."""
    if config.noise_scale is not None or not needs_noise_scale(config.perturbations):
        return config
    source = open_for(train_split, "motion noise (scale from the train split)",
                      missing="needs a train split, and this run has none",
                      hint="pass --noise-scale (the release: the mean per-dimension std of the training motion)")
    return replace(config, noise_scale=train_noise_scale(source))
