"""The same small sweep run locally and on a 2-worker Dask cluster: wall time side by side, overhead per task.

Rows (each a fresh ``dyadbench sweep`` process writing into an empty folder, embedded corpus, --no-per-clip):
- local, ``--jobs 1`` (one process) and ``--jobs 2`` (each run's clips in 2 worker processes);
- ``--scheduler ADDRESS`` of a 2-worker ``LocalCluster`` started beforehand (an existing cluster; one task
  per run), its start-up time given apart;
- ``--scheduler local:2`` (the cluster started and closed by the command itself).

Overhead per task: the mean round trip of a no-op task on the same cluster (submitted one after another),
and the worker-seconds per run not spent computing, (2 x cluster wall - local --jobs 1 wall) / runs.
The cluster's result files are checked equal to the local ones (metrics and everything but timing and
environment).

    nice -n 10 python benchmarks/bench_dask_sweep.py            # 3 models x 3 contexts, 8 clips each
    nice -n 10 python benchmarks/bench_dask_sweep.py --clips 4  # quick look

Writes benchmarks/results/dask_sweep.{json,md} (``--out`` elsewhere). On a machine shared with other work
every wall time stretches; the rows run one after another in the same conditions.
"""

from __future__ import annotations

import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import click

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from output import RESULTS, Transcript, preformatted, write_result  # noqa: E402  (benchmarks/output.py)

from distributed import Client, LocalCluster  # noqa: E402

MODELS = "zero,mean-frame,mime"
CONTEXTS = "0,3,7"
NOOP_TASKS = 200
DIFFERS = ("timing", "environment", "created_utc")


def sweep(out: Path, clips: int, *options: str) -> float:
    """Wall seconds of one ``dyadbench sweep`` process into ``out``."""
    command = [sys.executable, "-m", "dyadbench", "sweep", "--models", MODELS, "--splits", "test", "--contexts",
               CONTEXTS, "--clips", str(clips), "--no-per-clip", "--out", str(out), *options]
    start = time.perf_counter()
    run = subprocess.run(command, capture_output=True, text=True)
    wall = time.perf_counter() - start
    if run.returncode != 0:
        raise SystemExit(f"{' '.join(command)} failed:\n{run.stderr[-3000:]}")
    return wall


def comparable(path: Path) -> dict:
    data = json.loads(path.read_text())
    for key in DIFFERS:
        data.pop(key)
    data["notes"] = [n for n in data["notes"] if not n.startswith("scores reused")]
    return data


def same_results(a: Path, b: Path) -> tuple[int, bool]:
    """(files, whether every result file under ``a`` equals its twin under ``b`` but for timing/environment)."""
    files = sorted(p.relative_to(a) for p in a.rglob("*.json"))
    twins = sorted(p.relative_to(b) for p in b.rglob("*.json"))
    return len(files), files == twins and all(comparable(a / f) == comparable(b / f) for f in files)


def _noop() -> None:
    return None


@click.command()
@click.option("--clips", default=8, show_default=True, type=click.IntRange(min=1), help="Clips per run.")
@click.option("--out", default=RESULTS / "dask_sweep", show_default=True, type=click.Path(path_type=Path),
              help="Result file stem.")
def main(clips: int, out: Path) -> None:
    transcript = Transcript()
    say = transcript.say
    runs = len(MODELS.split(",")) * len(CONTEXTS.split(","))
    with tempfile.TemporaryDirectory(prefix="bench-dask-") as tmp:
        tmp = Path(tmp)
        rows = [("local, --jobs 1", sweep(tmp / "jobs1", clips, "--jobs", "1")),
                ("local, --jobs 2", sweep(tmp / "jobs2", clips, "--jobs", "2"))]
        start = time.perf_counter()
        with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster, \
                Client(cluster) as client:
            started = time.perf_counter() - start
            client.submit(_noop, pure=False).result()  # workers answering
            noop_start = time.perf_counter()
            for _ in range(NOOP_TASKS):
                client.submit(_noop, pure=False).result()
            noop_s = (time.perf_counter() - noop_start) / NOOP_TASKS
            existing = sweep(tmp / "existing", clips, "--scheduler", cluster.scheduler_address)
        rows.append(("--scheduler ADDRESS (2 workers, already running)", existing))
        rows.append(("--scheduler local:2 (cluster start included)", sweep(tmp / "local2", clips, "--scheduler",
                                                                           "local:2")))
        checks = [(name, *same_results(tmp / "jobs1", tmp / folder))
                  for name, folder in (("--jobs 2", "jobs2"), ("existing cluster", "existing"),
                                       ("local:2", "local2"))]
    local = rows[0][1]
    say(f"sweep: models {MODELS}, split test of the embedded corpus, contexts {CONTEXTS}, {clips} clips per run: "
        f"{runs} runs (one task each on a cluster)")
    say(f"{'how':<50} {'wall s':>8} {'vs --jobs 1':>12}")
    for name, wall in rows:
        say(f"{name:<50} {wall:>8.1f} {local / wall:>11.2f}x")
    say(f"\n2-worker LocalCluster start: {started:.1f} s (not in the ADDRESS row)")
    say(f"no-op task round trip on it: {noop_s * 1e3:.1f} ms per task (mean of {NOOP_TASKS}, one after another)")
    say(f"worker-seconds per run not spent computing, (2 x {existing:.1f} - {local:.1f}) / {runs}: "
        f"{(2 * existing - local) / runs:.2f} s (each worker builds the model and opens the split per run)")
    for name, files, same in checks:
        say(f"result files of {name} equal to --jobs 1 (but timing and environment): {same} ({files} files)")
    data = {"clips": clips, "runs": runs, "wall_s": dict(rows), "cluster_start_s": started,
            "noop_task_s": noop_s, "same_results": {name: same for name, _, same in checks}}
    text = preformatted("A small sweep locally and on a 2-worker Dask cluster", transcript.text())
    print("wrote", *write_result(out, text, seed=0, data=data))


if __name__ == "__main__":
    main()
