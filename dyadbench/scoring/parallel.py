"""Run a per-item function over many items in worker processes, one BLAS/OpenMP thread each.

Per-clip metrics are small linear-algebra problems (50x50 matrices, k-means on ~1000 frames):
multi-threaded BLAS/OpenMP gains nothing on them and, with several processes on the same cores,
oversubscribes the machine badly. So every worker (and the calling process when ``jobs == 1``)
runs with ``threadpoolctl`` limits of :data:`THREADS_PER_JOB` thread. Results come back in input
order; the numbers do not depend on ``jobs``. An error raised for an item in a worker is raised here
as it would be with ``jobs == 1`` (:func:`dyadbench.workers.process_map`).
"""

from __future__ import annotations

import multiprocessing
from typing import Callable, Iterator, Sequence, TypeVar

from threadpoolctl import threadpool_limits
from tqdm import tqdm

from dyadbench.workers import process_map

T = TypeVar("T")
R = TypeVar("R")

THREADS_PER_JOB = 1
_worker_limits = None  # keeps the worker's thread limits alive for its lifetime


def _limit_worker_threads() -> None:
    global _worker_limits
    _worker_limits = threadpool_limits(limits=THREADS_PER_JOB)


def map_items(fn: Callable[[T], R], items: Sequence[T], *, jobs: int = 1, desc: str = "scoring",
              chunksize: int | None = None) -> Iterator[R]:
    """Yield ``fn(item)`` for each item, in order, using ``jobs`` processes (1 = this process).

    ``fn`` must be a module-level function (it is sent to the workers by reference). Workers are
    forked (no re-import of the caller's script, so no ``__main__`` guard is needed) and set their
    thread limits before any work. A progress bar is shown on a terminal.
    """
    bar = tqdm(total=len(items), desc=desc, unit="clip", disable=None, leave=False)
    try:
        if jobs <= 1 or len(items) <= 1:
            with threadpool_limits(limits=THREADS_PER_JOB):
                for item in items:
                    yield fn(item)
                    bar.update()
            return
        chunk = chunksize or max(1, min(16, len(items) // (4 * jobs)))
        for result in process_map(fn, items, jobs=jobs, context=multiprocessing.get_context("fork"),
                                  initializer=_limit_worker_threads, chunksize=chunk):
            yield result
            bar.update()
    finally:
        bar.close()
