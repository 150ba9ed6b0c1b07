"""``--scheduler`` of ``eval``, ``sweep``, ``score`` and ``robustness``: their work on a Dask cluster
(:mod:`dyadbench.distributed`); ``sweep`` sends one task per run (:class:`ClusterSweep`)."""

from __future__ import annotations

import functools
from pathlib import Path
from typing import Callable

import click
from click.core import ParameterSource

from dyadbench import distributed
from dyadbench.errors import ConfigError, DyadbenchError
from dyadbench.protocol.config import ProtocolConfig


def scheduler_option(f: Callable) -> Callable:
    """Add ``--scheduler`` (env ``DYADBENCH_SCHEDULER``) to a command: with it, the command runs with that
    cluster active and, unless ``--jobs`` was given, as many parallel tasks as the cluster has worker threads
    (at least 2, so the work goes to the workers). Place it right above the command's function."""

    @functools.wraps(f)
    def command(*args, scheduler: str | None, **kwargs):
        if not scheduler:
            return f(*args, **kwargs)
        with distributed.connected(scheduler, device=kwargs.get("device", "cpu")) as cluster:
            ctx = click.get_current_context()
            if "jobs" in kwargs and ctx.get_parameter_source("jobs") is ParameterSource.DEFAULT:
                kwargs["jobs"] = max(2, cluster.slots)
            return f(*args, **kwargs)

    return click.option(
        "--scheduler", envvar=distributed.SCHEDULER_ENV, default=None, metavar="ADDRESS|local:N",
        help="Run the work on a Dask cluster: the address of its scheduler (e.g. tcp://host:8786) or local:N "
             "for a local cluster of N workers started here [env DYADBENCH_SCHEDULER]. --jobs then defaults to "
             "the cluster's worker threads. Workers must see the data at the same path (the embedded corpus "
             f"is generated on each worker and its digest checked); only this process writes files. Needs the "
             f"optional extra: {distributed.EXTRA}.")(command)


def _sweep_run(name: str, source, train_split, config: ProtocolConfig, *, cfg_scale: float, weights: Path | None,
               clips: int | None, threads: int | None, extra: dict, check: Callable[[dict], None] | None,
               unchanged: type, device: str, batch: int):
    """On a worker: one sweep run in this process (None when ``check`` finds the stored result unchanged)."""
    from dyadbench.cli.eval import run_one  # noqa: PLC0415  (dyadbench.cli.eval uses this module's option)

    try:
        return run_one(name, source, train_split, config, cfg_scale=cfg_scale, weights=weights, clips=clips,
                       jobs=1, predictions_dir=None, threads=threads or 1, extra=extra, check_configuration=check,
                       device=device, batch=batch)
    except unchanged:
        return None


class ClusterSweep:
    """``sweep``'s stand-in for its ``run_to_file`` on a cluster: each call submits the run as one task;
    :meth:`finish` writes each result as it arrives (here, atomically: ``write(result, path, per_clip)``) and
    reports the runs that failed, after the others finished."""

    def __init__(self, check: Callable[[Path], Callable | None], write: Callable, unchanged: type):
        self._check, self._write, self._unchanged = check, write, unchanged
        self._pending: list = []

    def __call__(self, path: Path, name: str, source, train_split, config: ProtocolConfig, *, cfg_scale: float,
                 weights: Path | None, clips: int | None, jobs: int, threads: int | None, extra: dict, force: bool,
                 per_clip: bool, preds: Path | None = None, device: str = "cpu", batch: int = 1) -> None:
        if preds is not None:
            raise ConfigError("--keep-predictions cannot be used with --scheduler: predictions stay on the workers")
        check = self._check(path) if path.exists() and not force else None
        future = distributed.submit(_sweep_run, name, source, train_split, config, cfg_scale=cfg_scale,
                                    weights=weights, clips=clips, threads=threads, extra=extra, check=check,
                                    unchanged=self._unchanged, device=device, batch=batch)
        self._pending.append(((path, per_clip), future))

    def finish(self) -> None:
        """Wait for every submitted run; raise once all are done if any failed (re-running does the rest)."""
        failed = []
        for (path, per_clip), result, error in distributed.completed(self._pending):
            if error is not None:
                failed.append(path)
                click.echo(f"error: {path}: {type(error).__name__}: {error}", err=True)
            elif result is None:
                click.echo(f"skip {path} (same configuration; --force re-runs)")
            else:
                self._write(result, path, per_clip)
        total, self._pending = len(self._pending), []
        if failed:
            raise DyadbenchError(f"{len(failed)} of {total} runs failed on the cluster (listed above); the sweep "
                                 f"run again does only the runs without a current result file")
