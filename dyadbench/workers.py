"""Ordered maps over worker processes whose errors reach the caller exactly as with one process.

:func:`process_map` yields ``fn(item)`` for each item, in input order, computed by ``jobs`` worker
processes. An exception raised by ``fn`` in a worker is raised by the iteration in the caller (same
type and message: every :mod:`dyadbench.errors` type pickles to itself); one whose type cannot make
the trip back (a third-party exception that does not unpickle) arrives as a ``RuntimeError`` with its
type, message and worker traceback, instead of breaking the pool (``BrokenProcessPool``). An exception
raised by the worker initialiser does not break the pool either: it is kept and raised by the worker's
first item instead. On an error, or when the caller stops iterating, pending items are cancelled
rather than computed. While a Dask cluster is active (``--scheduler``, :func:`dyadbench.distributed.connected`)
the same chunks go to its workers instead (:func:`dyadbench.distributed.cluster_map`), with the same order
and errors.
"""

from __future__ import annotations

import functools
import pickle
import traceback
from concurrent.futures import ProcessPoolExecutor
from multiprocessing.context import BaseContext
from typing import Callable, Iterator, Sequence, TypeVar

from dyadbench import distributed

T = TypeVar("T")
R = TypeVar("R")

_init_error: BaseException | None = None  # what this worker's initialiser raised, if anything


def _guarded_init(initializer: Callable[..., None] | None, args: tuple) -> None:
    global _init_error
    _init_error = None
    if initializer is None:
        return
    try:
        initializer(*args)
    except Exception as exc:  # noqa: BLE001  (re-raised by every item this worker is given)
        _init_error = exc


def _receivable(exc: BaseException) -> bool:
    """Whether ``exc`` survives the trip back to the caller (pickled and rebuilt)."""
    try:
        pickle.loads(pickle.dumps(exc))
    except Exception:  # noqa: BLE001  (any failure means the caller could not receive it)
        return False
    return True


def _guarded_call(fn: Callable[[T], R], item: T) -> R:
    if _init_error is not None:
        raise _init_error
    try:
        return fn(item)
    except Exception as exc:
        if _receivable(exc):
            raise
        error = RuntimeError(f"{type(exc).__name__} in a worker process: {exc}")
        error.worker_traceback = "".join(traceback.format_exception(exc))  # as text: it pickles
    # raised outside the handler, so it carries no context: a pickler that follows causes and contexts
    # (Dask's tblib) could not send it either
    raise error


def process_map(fn: Callable[[T], R], items: Sequence[T], *, jobs: int, context: BaseContext,
                initializer: Callable[..., None] | None = None, initargs: tuple = (),
                chunksize: int = 1) -> Iterator[R]:
    """Yield ``fn(item)`` for each of ``items`` in order, from ``jobs`` processes of ``context``.

    ``fn`` and ``initializer`` must be module-level functions (they are sent to the workers by
    reference); ``initializer(*initargs)`` runs once in each worker before its first item.
    """
    if distributed.active() is not None:
        yield from distributed.cluster_map(fn, items, initializer=initializer, initargs=initargs, chunksize=chunksize)
        return
    pool = ProcessPoolExecutor(max_workers=jobs, mp_context=context,
                               initializer=_guarded_init, initargs=(initializer, tuple(initargs)))
    try:
        yield from pool.map(functools.partial(_guarded_call, fn), items, chunksize=chunksize)
    finally:
        pool.shutdown(wait=True, cancel_futures=True)
