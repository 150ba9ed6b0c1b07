"""Helpers shared by the synthetic-layout writers: argument checks and an ordered, optionally parallel map."""

from __future__ import annotations

from concurrent.futures import ProcessPoolExecutor
from typing import Callable, Sequence, TypeVar

from tqdm import tqdm

from dyadbench.errors import ConfigError

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
