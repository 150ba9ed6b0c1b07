"""Streaming read and score of a 2,000-dyad split in the Seamless Interaction layout: files/s and peak memory.

The split is generated once by :func:`dyadbench.synth.seamless_writer.write_seamless_split` (``--dyads``
dyads of ``--seconds`` seconds, label ``improvised``, split ``test``, seed ``--seed``; the writer's
simulated corpus problems included: every 10th dyad has an empty bundle, one without movement features,
one in the per-modality layout) and cached in dyadbench's cache folder under ``bench-seamless-scale/``
(``--cache`` elsewhere), so re-runs measure reading only. Each phase runs in a child process forked from
the script's (which has imported everything and holds no data), one file at a time in that process:

- **discover**: :class:`dyadbench.datasets.seamless.SeamlessSplit` of ``improvised/test``: globbing, the
  npz member lists and the movement features' frame counts (npy headers only), pairing into dyads, skips;
  files/s = participant bundles found per second.
- **read**: discovery (untimed), then every usable dyad through :class:`~dyadbench.datasets.seamless.SeamlessSource`
  ``load`` (both participants' movement features in the ``seamless`` layout and their 48 kHz speech
  resampled to 16 kHz), one dyad in memory at a time; files/s = participant bundles read per second.
  Run on the first ``--small`` dyads and on the whole split: equal peak memory at both sizes is what
  "bounded" means here.
- **score**: :func:`dyadbench.scoring.seamless.score_paths` of a prediction folder (the partner's movement
  features as the agent's prediction, i.e. ``mime``) against the whole split, ``--jobs`` processes, the
  suite's metrics on every agent with a prediction; files/s = agents per second (each: one prediction file
  and two participant bundles read; those with fewer than 40 frames valid for both are read and excluded),
  discovery of the whole split included (``score_paths`` opens it). Predictions are written for the first ``--small``
  and ``--score-dyads`` usable dyads (the suite's FD and P-FD over 128 and 256 dims cost a fraction of a
  second per agent, so scoring all 3,200 agents would take far longer than reading them); the other
  dyads are still discovered, paired and reported as missing, and the same two sizes show whether
  scoring memory grows with the number of agents.
- **imports**: a child that does nothing: the floor of every peak below (the forked process's resident
  set starts with the parent's: interpreter and libraries, NumPy, SciPy, scikit-learn and torch).
  With ``--jobs 1`` a score run first scores one random agent, untimed, so it times scoring and not the
  compilation of the metrics' numba code (its memory is in the peak); with more jobs each worker compiles
  on its first agent, inside the timed run.
- **Dask** (``--scheduler local:N``; ``none`` skips): the same reads and scores through a ``LocalCluster``
  of N one-thread worker processes (:func:`dyadbench.distributed.connected`, as ``--scheduler local:N``
  does), started in the phase's process and not timed (its start is reported). *read*: the usable dyads in
  chunks of ``--dask-chunk``, one task each (:func:`dyadbench.distributed.submit`): a worker re-opens the
  split at the same path (:class:`~dyadbench.distributed.SplitOnWorker`, what ``eval --scheduler`` does
  with its chunks of clips) and loads its dyads one at a time. *score*: ``score_paths`` with ``jobs`` = N
  under the cluster, so the per-agent tasks (each reading its prediction file and two bundles) run on the
  workers (``score --scheduler``), on the same ``--score-dyads`` predictions as the one-machine run.
  Peak memory: the client's (its process, which also runs Dask's scheduler) and the largest worker's
  (``ru_maxrss`` read on each worker before the cluster closes; each worker imports the libraries itself).

Peak memory: ``resource.getrusage(RUSAGE_SELF).ru_maxrss`` of the phase's process (peak resident set, KiB
on Linux: interpreter, libraries and data), and with ``--jobs`` > 1 the largest scoring worker's
(``RUSAGE_CHILDREN``). Not tracemalloc: the peak includes NumPy/SciPy buffers and the libraries.

    nice -n 10 python benchmarks/bench_seamless_scale.py          # 2,000 dyads of 4 s
    python benchmarks/bench_seamless_scale.py --dyads 200 --out /tmp/quick   # a quick look

Writes benchmarks/results/seamless_scale.{json,md} (``--out`` elsewhere).
"""

from __future__ import annotations

import multiprocessing
import os
import resource
import sys
import time
import traceback
from pathlib import Path

import click
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from output import RESULTS, Transcript, write_result  # noqa: E402  (benchmarks/output.py)
from timing import timed  # noqa: E402  (benchmarks/timing.py)

from dyadbench.datasets.seamless import SEAMLESS, SeamlessSource, SeamlessSplit, read_motion  # noqa: E402
from dyadbench.datasets.seamless_files import discover  # noqa: E402
from dyadbench.metrics.seamless import item_metrics  # noqa: E402
from dyadbench.paths import cache_dir  # noqa: E402
from dyadbench.scoring.seamless import score_paths  # noqa: E402
from dyadbench.synth.seamless_writer import write_seamless_split  # noqa: E402

SPLIT = "improvised/test"


def _peak_kib() -> dict[str, int]:
    """Peak resident set of this process and of its largest finished child, KiB (Linux ru_maxrss)."""
    return {"self": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss,
            "children": resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss}


def _read_dyads(source: SeamlessSource, ids: list[str]) -> int:
    """On a worker: load each dyad of ``ids``, one at a time; participant bundles read."""
    return sum(len(source.load(clip_id).participants) for clip_id in ids)


def _worker_peak_kib() -> int:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss


def _run_dask(phase: str, root: Path, pred: Path | None, scheduler: str, chunk: int) -> dict:
    """One phase through a local Dask cluster (see the module docstring): its start untimed, then the work."""
    from dyadbench import distributed  # noqa: PLC0415  (Dask is imported only here)

    started = time.perf_counter()
    with distributed.connected(scheduler) as cluster:
        start_s = time.perf_counter() - started
        if phase == "dask-read":
            source = SeamlessSource(root, SPLIT)
            ids = source.clip_ids()  # discovery on the client, measured on its own above

            def read() -> int:
                futures = [distributed.submit(_read_dyads, source, ids[i:i + chunk]) for i in range(0, len(ids), chunk)]
                return sum(f.result() for f in futures)
            files, seconds, cpu = timed(read)
            result = {"files": files, "seconds": seconds, "cpu_s": cpu, "tasks": -(-len(ids) // chunk)}
        else:
            report, seconds, cpu = timed(lambda: score_paths(pred, root, split=SPLIT, jobs=cluster.slots))
            result = {"files": len(report.per_item) + len(report.excluded), "scored": len(report.per_item),
                      "excluded": len(report.excluded), "seconds": seconds, "cpu_s": cpu,
                      "expected": report.coverage["expected"], "fd_expression": report.metrics["fd_expression"],
                      "frames_excluded": report.coverage["frames_excluded"]}
        workers = cluster.client.run(_worker_peak_kib)
    return {**result, "cluster_start_s": start_s, "workers": len(workers),
            "largest_worker_kib": max(workers.values())}


def _run_phase(phase: str, root: Path, limit: int | None, pred: Path | None, jobs: int,
               scheduler: str | None = None, chunk: int = 100) -> dict:
    """One measured phase in this process (see the module docstring)."""
    if phase.startswith("dask-"):
        return _run_dask(phase, root, pred, scheduler, chunk)
    if phase == "imports":
        return {"files": 0, "seconds": 0.0}
    if phase == "discover":
        data, seconds, cpu = timed(lambda: SeamlessSplit.open(root, SPLIT))
        bundles = sum(len(b) for b in discover(root, SPLIT).bundles.values())  # counted after the timed run
        return {"files": bundles, "seconds": seconds, "cpu_s": cpu, "usable_dyads": len(data.pairs),
                "skipped_dyads": data.skipped_dyads()}
    if phase == "read":
        source = SeamlessSource(root, SPLIT)
        ids = source.clip_ids()[:limit]  # discovery, measured on its own above

        def read() -> int:
            return sum(len(source.load(clip_id).participants) for clip_id in ids)
        files, seconds, cpu = timed(read)
        return {"files": files, "seconds": seconds, "cpu_s": cpu}
    if jobs == 1:
        _warm_up()
    report, seconds, cpu = timed(lambda: score_paths(pred, root, split=SPLIT, jobs=jobs))
    return {"files": len(report.per_item) + len(report.excluded), "scored": len(report.per_item),
            "excluded": len(report.excluded), "seconds": seconds, "cpu_s": cpu, "expected": report.coverage["expected"],
            "fd_expression": report.metrics["fd_expression"], "frames_excluded": report.coverage["frames_excluded"]}


def _child(fn, args: tuple, results) -> None:
    try:
        results.put(("ok", fn(*args), _peak_kib()))
    except BaseException:  # noqa: BLE001  (reported by the parent)
        results.put(("error", traceback.format_exc(), None))


def _forked(fn, *args):
    """(``fn(*args)``, peak memory) from a child process forked from this one, which holds the imports and
    no data (generation and prediction writing run in children too)."""
    context = multiprocessing.get_context("fork")
    results = context.Queue()
    process = context.Process(target=_child, args=(fn, args, results))
    process.start()
    status, value, peak = results.get()
    process.join()
    if status != "ok":
        raise RuntimeError(f"{fn.__name__} failed in its process:\n{value}")
    return value, peak


def _measure(phase: str, root: Path, *, limit: int | None = None, pred: Path | None = None, jobs: int = 1,
             scheduler: str | None = None, chunk: int = 100) -> dict:
    result, peak = _forked(_run_phase, phase, root, limit, pred, jobs, scheduler, chunk)
    return {**result, "peak_kib": peak}


def _warm_up() -> None:
    """Score one random agent (untimed), so a score run times scoring, not the compilation of the metrics'
    numba code. Only in a process that forks no workers afterwards: numba's OpenMP layer forbids it."""
    rng = np.random.default_rng(0)
    motion = [rng.standard_normal((120, SEAMLESS.dim)) for _ in range(3)]
    for m in motion:
        m[:, -1] = 1.0
    item_metrics(*motion, SEAMLESS, seed=0)


def _split(cache: Path, dyads: int, seconds: float, seed: int, jobs: int) -> Path:
    """The cached synthetic split (generated on first use)."""
    root = cache / f"d{dyads}-s{seconds:g}-seed{seed}"
    if not (root / SPLIT / "synthetic.json").is_file():
        _, wall, _ = timed(lambda: write_seamless_split(root, split="test", clips=dyads, seed=seed, jobs=jobs,
                                                        duration_s=seconds, force=True))
        print(f"generated {dyads} dyads in {wall:.0f} s into {root}")
    return root


def _predictions(root: Path, dyads: int) -> Path:
    """``mime`` predictions (each agent's = its partner's movement features) for the first ``dyads`` usable
    dyads, cached beside the split."""
    folder = root.parent / f"{root.name}-pred{dyads}"
    if not (folder / "done").is_file():  # the marker is written last: an interrupted folder is rewritten
        folder.mkdir(parents=True, exist_ok=True)
        data = SeamlessSplit.open(root, SPLIT)
        for first, second in [data.pairs[d] for d in sorted(data.pairs)[:dyads]]:
            for agent, partner in ((first, second), (second, first)):
                np.save(folder / f"{agent.stem}.npy", read_motion(partner))
        (folder / "done").write_text(f"{dyads}\n")
    return folder


def _size_mib(root: Path) -> float:
    return sum(p.stat().st_size for p in (root / SPLIT).rglob("*") if p.is_file()) / 2 ** 20


@click.command()
@click.option("--dyads", default=2000, show_default=True, type=click.IntRange(min=10), help="Dyads in the split.")
@click.option("--seconds", default=4.0, show_default=True, type=click.FloatRange(min=2.0),
              help="Length of each dyad (30 Hz movement, 48 kHz speech).")
@click.option("--small", default=25, show_default=True, type=click.IntRange(min=1),
              help="Dyads of the small read and score runs (peak memory compared with the large ones).")
@click.option("--score-dyads", default=100, show_default=True, type=click.IntRange(min=1),
              help="Usable dyads with predictions in the large score run (both agents of each scored).")
@click.option("--jobs", "-j", default=1, show_default=True, type=click.IntRange(min=1),
              help="Scoring processes (and generation processes on the first run).")
@click.option("--scheduler", default="local:2", show_default=True,
              help="Dask cluster of the distributed read and score runs (local:N), or 'none' to skip them.")
@click.option("--dask-chunk", default=100, show_default=True, type=click.IntRange(min=1),
              help="Dyads per task of the distributed read.")
@click.option("--seed", default=0, show_default=True, help="Seed of the generated split and of the scorer.")
@click.option("--cache", default=None, type=click.Path(file_okay=False, path_type=Path),
              help="Where the generated split is kept. Default: <dyadbench cache>/bench-seamless-scale.")
@click.option("--out", default=RESULTS / "seamless_scale", show_default=True, type=click.Path(path_type=Path),
              help="Result to write (.json and .md).")
def main(dyads: int, seconds: float, small: int, score_dyads: int, jobs: int, scheduler: str, dask_chunk: int,
         seed: int, cache: Path | None, out: Path) -> None:
    """Print files/s and peak memory of streaming discovery, reading and scoring of a synthetic split."""
    say = (transcript := Transcript()).say
    root, _ = _forked(_split, cache or cache_dir() / "bench-seamless-scale", dyads, seconds, seed, jobs)
    started = time.perf_counter()
    runs = [("imports only", "imports", {}), ("discover (whole split)", "discover", {}),
            (f"read, first {small} dyads", "read", {"limit": small}), ("read, whole split", "read", {})]
    for n in (small, score_dyads):
        runs.append((f"score, {n} dyads with predictions, jobs {jobs}", "score",
                     {"pred": _forked(_predictions, root, n)[0], "jobs": jobs}))
    score_run = len(runs) - 1  # the one-machine run the summary lines describe
    if scheduler != "none":
        runs += [(f"read, whole split, Dask {scheduler} ({dask_chunk} dyads per task)", "dask-read",
                  {"scheduler": scheduler, "chunk": dask_chunk}),
                 (f"score, {score_dyads} dyads with predictions, Dask {scheduler}", "dask-score",
                  {"pred": runs[score_run][2]["pred"], "scheduler": scheduler})]
    rows = []
    for name, kind, kwargs in runs:
        result = _measure(kind, root, **kwargs)
        rows.append({"run": name, "phase": kind, **result})
    load = os.getloadavg()[0]

    floor = rows[0]["peak_kib"]["self"] / 1024
    say(f"# Seamless Interaction layout, streaming: {dyads} dyads of {seconds:g} s ({_size_mib(root):.0f} MiB on "
        f"disk), split {SPLIT}; {os.cpu_count()} CPUs; load average at the end: {load:.2f}\n")
    say(f"discovery: {rows[1]['usable_dyads']} usable dyads, {rows[1]['skipped_dyads']} skipped (simulated empty "
        f"bundles and vendor without movement features)\n")
    say("| run | files | seconds | files/s | peak RSS MiB | above imports MiB | largest worker MiB |\n"
        "|---|---:|---:|---:|---:|---:|---:|")
    for row in rows[1:]:
        peak = row["peak_kib"]["self"] / 1024
        worker = f"{row['peak_kib']['children'] / 1024:.0f}" if jobs > 1 and row["phase"] == "score" else "-"
        if row["phase"].startswith("dask-"):
            worker = f"{row['largest_worker_kib'] / 1024:.0f}"
        say(f"| {row['run']} | {row['files']} | {row['seconds']:.1f} | {row['files'] / row['seconds']:.1f} | "
            f"{peak:.0f} | {peak - floor:.0f} | {worker} |")
    say(f"\nimports only: peak RSS {floor:.0f} MiB (the floor of every run).")
    say("files: participant bundles found (discover), participant bundles read with speech resampled to 16 kHz "
        "(read; discovery not timed), agents with predictions, each one prediction file and two bundles (score; "
        f"discovery of the whole split timed). The score runs pair the whole split "
        f"({rows[score_run]['expected']} agents expected) and score the agents with predictions (mime: the "
        "partner's features); "
        f"{rows[score_run]['excluded']} of the large run's {rows[score_run]['files']} had fewer than 40 frames valid "
        "for both participants and were excluded by the suite.")
    if scheduler != "none":
        dread, dscore = rows[-2], rows[-1]
        same = dscore["fd_expression"] == rows[score_run]["fd_expression"]
        say(f"Dask ({scheduler}, {dscore['workers']} one-thread worker processes on this machine): cluster start "
            f"{dread['cluster_start_s']:.1f} s and {dscore['cluster_start_s']:.1f} s, not timed; the read ran "
            f"{dread['tasks']} tasks; the score run scored the same {dscore['files']} agents as the one-machine "
            f"run, FD expression {'equal' if same else 'DIFFERENT'} "
            f"({dscore['fd_expression']!r} vs {rows[score_run]['fd_expression']!r}). 'peak RSS' of a Dask run is "
            "the client's (it also runs the scheduler), 'largest worker' the largest worker process's.")
    rows_summary = rows[score_run]
    total_agents = rows_summary["expected"]
    rate = rows_summary["files"] / rows_summary["seconds"]
    say(f"at the large score run's rate, all {total_agents} agents of the split: about {total_agents / rate:.0f} s "
        f"with jobs {jobs}.")
    say(f"\npeak RSS: ru_maxrss of a process forked per run (interpreter, libraries and data); 'largest worker' "
        f"with --jobs > 1 and with Dask (where each worker compiles the metrics' numba code on its first agent, "
        f"inside the timed run). Total wall time of the runs: {time.perf_counter() - started:.0f} s.")
    data = {"dyads": dyads, "seconds_per_dyad": seconds, "split": SPLIT, "disk_mib": _size_mib(root),
            "jobs": jobs, "scheduler": scheduler, "load_average_end": load, "runs": rows}
    print("wrote", *write_result(out, transcript.text(), seed=seed, data=data))


if __name__ == "__main__":
    main()
