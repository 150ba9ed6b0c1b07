"""Work on a Dask cluster (``--scheduler``): the same tasks as local worker processes, sent to Dask workers.

:func:`connected` opens a ``dask.distributed`` client for ``--scheduler ADDRESS`` (an existing scheduler,
e.g. ``tcp://host:8786``) or ``local:N`` (a ``LocalCluster`` of N one-thread worker processes started
here) and makes it the *active* cluster of this thread for the duration. While one is active,
:func:`dyadbench.workers.process_map` sends its items to the cluster (:func:`cluster_map`) instead of
local processes: a run's chunks of clips (:mod:`dyadbench.protocol.runner`) and the per-clip metrics
(:mod:`dyadbench.scoring.parallel`) then run on the workers, in the same chunks, in input order, an
error raised for an item raised here. ``sweep`` submits whole runs instead (:func:`submit`,
:func:`completed`). Workers compute; only the client writes result files.

A task whose worker dies is run again on another worker (Dask's ``allowed-failures``), and a task that
raises is retried :data:`RETRIES` times before its error is reported.

Data on workers (:class:`SplitOnWorker`): a generated split (the embedded corpus) is re-opened on the
worker, generated there from its seed when absent, and its digest (:func:`dyadbench.provenance.split_digest`)
must equal the client's; any other split must be readable at the same path (a shared file system),
otherwise the task fails naming the worker and the folder.

GPU workers: with ``--device cuda`` every task asks for :data:`GPU_RESOURCE` = 1, so it runs only on
workers started with ``--resources GPU=1`` (one per GPU), one task per GPU at a time.

Dask is an optional extra (``pip install 'dyadbench[dask]'``): it is imported only by :func:`connected`.
"""

from __future__ import annotations

import contextlib
import contextvars
import hashlib
import os
import pickle
import socket
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Iterator, Sequence

from dyadbench.datasets.base import ClipSource
from dyadbench.errors import ConfigError, InputError
from dyadbench.provenance import split_digest
from dyadbench.registry import DATASETS

#: Environment variable read when ``--scheduler`` is not given.
SCHEDULER_ENV = "DYADBENCH_SCHEDULER"
#: How the optional dependency is installed.
EXTRA = "pip install 'dyadbench[dask]'"
#: Times a task that raised is run again before its error is reported.
RETRIES = 2
#: Worker resource a ``--device cuda`` task asks one unit of.
GPU_RESOURCE = "GPU"
#: Seconds to wait for an existing scheduler to answer.
CONNECT_TIMEOUT_S = 30


@dataclass(frozen=True)
class Cluster:
    """The active cluster: its client, how many tasks it runs at once, and what each task asks for."""

    client: Any
    slots: int
    resources: dict | None


_ACTIVE: contextvars.ContextVar[Cluster | None] = contextvars.ContextVar("dyadbench_cluster", default=None)


def active() -> Cluster | None:
    """The cluster opened by :func:`connected` in this thread, or None (work stays in local processes)."""
    return _ACTIVE.get()


def _dask():
    try:
        import distributed  # noqa: PLC0415  (optional extra, imported only when a cluster is asked for)
    except ImportError:
        raise ConfigError(f"--scheduler needs Dask, an optional extra: {EXTRA}") from None
    return distributed


def task_resources(device: str) -> dict | None:
    """What each task asks of a worker: one :data:`GPU_RESOURCE` for a CUDA device, nothing on CPU."""
    return {GPU_RESOURCE: 1} if device.startswith("cuda") else None


def local_workers(scheduler: str) -> int | None:
    """N of ``local:N`` (None for the address of an existing scheduler)."""
    if not scheduler.startswith("local:"):
        return None
    text = scheduler.removeprefix("local:")
    if not text.isdigit() or int(text) < 1:
        raise ConfigError(f"--scheduler {scheduler!r}: expected local:N with N >= 1 workers, or a scheduler address")
    return int(text)


def _slots(client, resources: dict | None, scheduler: str) -> int:
    """Worker threads able to run the tasks (those offering ``resources``, when asked for)."""
    workers = client.scheduler_info()["workers"].values()
    able = [w for w in workers
            if all(w.get("resources", {}).get(k, 0) >= v for k, v in (resources or {}).items())]
    if not able:
        wanted = ", ".join(f"{k}={v}" for k, v in (resources or {}).items())
        raise ConfigError(f"--scheduler {scheduler}: no worker of the cluster offers the resource {wanted} "
                          f"(start GPU workers with `dask worker ADDRESS --resources {GPU_RESOURCE}=1`, one per GPU)"
                          if resources else f"--scheduler {scheduler}: the cluster has no worker")
    return sum(w.get("nthreads", 1) for w in able)


@contextlib.contextmanager
def connected(scheduler: str, device: str = "cpu", local_resources: dict | None = None) -> Iterator[Cluster]:
    """Open the cluster ``scheduler`` names (an address, or ``local:N``) and make it the active one.

    ``local_resources``: resources each worker of a ``local:N`` cluster offers (e.g. ``{"GPU": 1}``); with
    ``device`` cuda they default to one GPU per worker (the workers then share this machine's GPUs).
    """
    n = local_workers(scheduler)
    dd = _dask()
    resources = task_resources(device)
    with contextlib.ExitStack() as stack:
        if n is not None:
            cluster = stack.enter_context(dd.LocalCluster(
                n_workers=n, threads_per_worker=1, processes=True, dashboard_address=None,
                resources=local_resources if local_resources is not None else resources))
            client = stack.enter_context(dd.Client(cluster))
        else:
            try:
                client = stack.enter_context(dd.Client(scheduler, timeout=CONNECT_TIMEOUT_S))
            except (OSError, TimeoutError) as exc:
                raise ConfigError(f"--scheduler {scheduler}: cannot reach a Dask scheduler there ({exc})") from None
        token = _ACTIVE.set(Cluster(client, _slots(client, resources, scheduler), resources))
        try:
            yield _ACTIVE.get()
        finally:
            _ACTIVE.reset(token)


@dataclass(frozen=True)
class SplitOnWorker:
    """A split as the client opened it, re-opened on a worker by :meth:`open` (see module docstring)."""

    source: ClipSource
    digest: str | None  # split_digest of a generated split (None: recorded data, read at its path)

    @classmethod
    def of(cls, source: ClipSource) -> "SplitOnWorker":
        return cls(source, split_digest(source) if source.generated_by() is not None else None)

    def open(self) -> ClipSource:
        source, folder = self.source, self.source.root
        where = f"worker {socket.gethostname()} (pid {os.getpid()})"
        if self.digest is None:
            if folder is not None and not Path(folder).exists():
                raise InputError(folder, f"{where} cannot see this data folder: a cluster's workers read the "
                                         f"data at the same path (a shared file system)")
            return source
        # generated: the worker's own copy (generated from its seed here when absent), checked by digest
        local = DATASETS.load(source.dataset)(Path(folder).parent if folder and Path(folder).is_dir() else None,
                                              source.split)
        actual = split_digest(local)
        if actual != self.digest:
            raise InputError(local.root, f"{where} holds the {source.dataset} {source.split} split with digest "
                                         f"{actual[:16]}, the client's is {self.digest[:16]} (install the same "
                                         f"dyadbench version on every worker)")
        return local


def on_worker(value):
    """``value`` with a :class:`SplitOnWorker` opened (what a task's arguments become on the worker)."""
    return value.open() if isinstance(value, SplitOnWorker) else value


def for_workers(value):
    """``value`` with a :class:`~dyadbench.datasets.base.ClipSource` wrapped in :class:`SplitOnWorker`."""
    return SplitOnWorker.of(value) if isinstance(value, ClipSource) else value


_INITIALISED: dict = {}  # on a worker: the key of the initialiser it last ran


def _run_chunk(key: str, initializer: Callable[..., None] | None, initargs: tuple, fn: Callable, chunk: list) -> list:
    """On a worker: run ``initializer(*initargs)`` unless it was the last one run here, then ``fn`` per item."""
    if initializer is not None and _INITIALISED.get("key") != key:
        _INITIALISED.pop("key", None)
        initializer(*(on_worker(a) for a in initargs))
        _INITIALISED["key"] = key
    return [fn(item) for item in chunk]


def cluster_map(fn: Callable, items: Sequence, *, initializer: Callable[..., None] | None = None,
                initargs: tuple = (), chunksize: int = 1) -> Iterator:
    """Yield ``fn(item)`` for each of ``items`` in order, computed on the active cluster in chunks of
    ``chunksize`` items; each worker runs ``initializer(*initargs)`` before its first chunk (clip sources
    among ``initargs`` re-opened there, :class:`SplitOnWorker`). The remote error of an item is raised here."""
    cluster = active()
    if cluster is None:
        raise ConfigError("no Dask cluster is active (dyadbench.distributed.connected)")
    initargs = tuple(for_workers(a) for a in initargs)
    key = hashlib.sha256(pickle.dumps((getattr(initializer, "__qualname__", None), initargs))).hexdigest()
    futures = [cluster.client.submit(_run_chunk, key, initializer, initargs, fn, list(items[i:i + chunksize]),
                                     retries=RETRIES, pure=False, resources=cluster.resources)
               for i in range(0, len(items), chunksize)]
    try:
        for future in futures:
            yield from future.result()
    finally:
        cluster.client.cancel(futures)


def _call(fn: Callable, args: tuple, kwargs: dict):
    return fn(*(on_worker(a) for a in args), **{k: on_worker(v) for k, v in kwargs.items()})


def submit(fn: Callable, *args, **kwargs):
    """A future of ``fn(*args, **kwargs)`` on the active cluster (clip sources re-opened on the worker,
    :class:`SplitOnWorker`; retried :data:`RETRIES` times)."""
    cluster = active()
    if cluster is None:
        raise ConfigError("no Dask cluster is active (dyadbench.distributed.connected)")
    return cluster.client.submit(_call, fn, tuple(for_workers(a) for a in args),
                                 {k: for_workers(v) for k, v in kwargs.items()},
                                 retries=RETRIES, pure=False, resources=cluster.resources)


def completed(tagged: list[tuple[Any, Any]]) -> Iterator[tuple[Any, Any, BaseException | None]]:
    """For ``(tag, future)`` pairs: ``(tag, result, None)`` or ``(tag, None, error)`` as each finishes."""
    dd = _dask()
    tags = {future.key: tag for tag, future in tagged}
    for future in dd.as_completed([f for _, f in tagged]):
        try:
            yield tags[future.key], future.result(), None
        except Exception as exc:  # noqa: BLE001  (reported per run by the caller; the others go on)
            yield tags[future.key], None, exc
