"""The 'synthetic-gaze' dataset: the embedded synthetic gaze–head sessions (:mod:`dyadbench.synth.gaze`),
written on first use in the gaze–head layout (:mod:`dyadbench.synth.gaze_writer`) and read with its
adapter (:mod:`dyadbench.datasets.gaze`).
"""

from __future__ import annotations

import sys
from pathlib import Path

from dyadbench import atomic
from dyadbench.datasets.base import DEFAULT_SPLIT
from dyadbench.datasets.gaze import GazeSource
from dyadbench.errors import ConfigError
from dyadbench.paths import cache_dir
from dyadbench.synth.gaze import SPLITS
from dyadbench.synth.gaze_writer import write_gaze_split
from dyadbench.synth.styles import GENERATOR_VERSION

SYNTHETIC_VERSION = 1
SYNTHETIC_SEED = 0


def synthetic_root() -> Path:
    """``<cache>/synthetic-gaze-v<gaze generator>.<speech generator>-seed0``: new versions never reuse old files."""
    return cache_dir() / f"synthetic-gaze-v{SYNTHETIC_VERSION}.{GENERATOR_VERSION}-seed{SYNTHETIC_SEED}"


def open_synthetic_split(root: Path | None, split: str | None) -> GazeSource:
    """The embedded synthetic gaze–head sessions: generated on first use into ``root`` (default: the cache)."""
    split = split or DEFAULT_SPLIT
    if split not in SPLITS:
        raise ConfigError(f"unknown synthetic gaze split {split!r} (known: {', '.join(SPLITS)})")
    in_cache = root is None  # the cache's split folders are dyadbench's own: replaced whatever they hold
    root = synthetic_root() if in_cache else Path(root)
    marker = root / split / ".complete.json"
    if not marker.is_file():  # absent, or left by an interrupted older version: (re)write the split whole
        print(f"dyadbench: generating the synthetic gaze-head {split} split (seed {SYNTHETIC_SEED}) into "
              f"{root / split} (first use only)", file=sys.stderr)
        summary = write_gaze_split(root, split=split, seed=SYNTHETIC_SEED, force=in_cache)
        atomic.write_json(marker, summary)
    source = GazeSource(root, split)
    source.dataset = "synthetic-gaze"
    return source
