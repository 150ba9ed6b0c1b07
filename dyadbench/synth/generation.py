"""Helpers shared by the synthetic-layout writers: argument checks, an ordered, optionally parallel map,
and the output folder of a generated split."""

from __future__ import annotations

import contextlib
import json
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Callable, Sequence, TypeVar

from tqdm import tqdm

from dyadbench.errors import ConfigError
from dyadbench.outputs import owned_folder

#: Summary file the dualtalk, react and l2l writers put in a split folder, written last.
SUMMARY = "synthetic.json"

T = TypeVar("T")
R = TypeVar("R")


def clip_count(clips: int | None, default: int, jobs: int) -> int:
    """The number of dialogues to write (``clips`` or the split's default); checks ``clips`` and ``jobs``."""
    n = default if clips is None else int(clips)
    if n < 1:
        raise ConfigError(f"--clips must be at least 1, got {n}")
    if jobs < 1:
        raise ConfigError(f"--jobs must be at least 1, got {jobs}")
    return n


def map_tasks(fn: Callable[[T], R], tasks: Sequence[T], *, jobs: int, desc: str, unit: str = "dialogue",
              progress: bool = True, chunksize: int = 2) -> list[R]:
    """``[fn(t) for t in tasks]`` in order, in ``jobs`` worker processes when jobs > 1, with a progress bar.

    ``fn`` must be a module-level function; results do not depend on ``jobs``.
    """
    bar = dict(total=len(tasks), desc=desc, unit=unit, disable=not progress)
    if jobs == 1:
        return [fn(t) for t in tqdm(tasks, **bar)]
    with ProcessPoolExecutor(max_workers=jobs) as pool:
        return list(tqdm(pool.map(fn, tasks, chunksize=chunksize), **bar))


def generated_split(folder: Path) -> bool:
    """True for a split folder the generator wrote before output folders carried a marker (its summary)."""
    try:
        return json.loads((folder / SUMMARY).read_text(encoding="utf-8")).get("generator") == "dyadbench.synth"
    except (OSError, ValueError, AttributeError):
        return False


def split_folder(folder: Path, layout: str, force: bool) -> contextlib.AbstractContextManager[Path]:
    """The output folder of one generated split (:func:`dyadbench.outputs.owned_folder`): written aside and
    swapped in when complete, so a previous split is replaced whole, never mixed with the new clips. A
    folder holding files the generator did not write is refused unless ``force``."""
    return owned_folder(folder, f"synth-{layout}", force=force, label=f"split folder {folder}",
                        legacy=generated_split)
