"""The README's main job end to end: corpus generation on a fresh cache, then the evaluation, then again warm.

The main job is ``dyadbench eval --model timar --dataset synthetic-v2 --split ood --context 7 --clips 20``
(the README's set-up line with the corpus named explicitly; default ``--batch`` and threads). Each step
is the real command in its own process, timed from the outside (wall seconds, CPU seconds of the process
and its workers from ``getrusage(RUSAGE_CHILDREN)``), with a temporary ``DYADBENCH_CACHE``:

1. **generate**: open the ``ood`` split of ``synthetic-v2`` in an empty cache, which generates it
   (``dyadbench.datasets.synthetic``): what a new checkout pays once before its first evaluation;
2. **eval, fresh cache**: the main job in another empty cache: generation, model load, 20 dialogues
   streamed and scored;
3. **eval, warm cache**: the main job again in the first cache, whose split now exists.

For each eval the result file's own ``timing.wall_s`` (the evaluation after the split is open: model
build, streaming, scoring) is reported beside the command's wall time (which adds interpreter start,
imports and, on a fresh cache, generation). The one-minute load average is read before and after each
step: on a machine shared with other jobs every time here is an upper bound for an idle one. Seeds: the
corpus's fixed seed and ``--seed 0``.

    nice -n 10 python benchmarks/bench_main_job.py

Writes benchmarks/results/main_job.{json,md} (``--out`` elsewhere).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from output import RESULTS, write_result  # noqa: E402  (benchmarks/output.py)

MAIN_JOB = ["eval", "--model", "timar", "--dataset", "synthetic-v2", "--split", "ood", "--context", "7",
            "--clips", "20", "--seed", "0"]
GENERATE = "from dyadbench.registry import DATASETS; DATASETS.load('synthetic-v2')(None, 'ood')"
#: Runs argv[1:] as a child; prints its wall seconds and CPU seconds (the child and its workers).
PROBE = """
import resource, subprocess, sys, time
start = time.perf_counter()
subprocess.run(sys.argv[1:], check=True, stdout=subprocess.DEVNULL)
wall = time.perf_counter() - start
usage = resource.getrusage(resource.RUSAGE_CHILDREN)
print(wall, usage.ru_utime + usage.ru_stime)
"""


def step(name: str, argv: list[str], cache: Path) -> dict:
    """Run ``argv`` with ``DYADBENCH_CACHE=cache``; wall and CPU seconds, load average before and after."""
    before = os.getloadavg()[0]
    env = {**os.environ, "DYADBENCH_CACHE": str(cache)}
    out = subprocess.run([sys.executable, "-c", PROBE, *argv], check=True, capture_output=True, text=True,
                         env=env).stdout.split()
    row = {"step": name, "wall_s": float(out[-2]), "cpu_s": float(out[-1]), "load_before": before,
           "load_after": os.getloadavg()[0]}
    print(row, flush=True)
    return row


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", default=str(RESULTS / "main_job"))
    args = parser.parse_args()
    dyadbench = [sys.executable, "-m", "dyadbench"]
    rows = []
    with tempfile.TemporaryDirectory(prefix="bench-main-job-") as tmp:
        warm, fresh = Path(tmp) / "cache-a", Path(tmp) / "cache-b"
        rows.append(step("generate the ood split (fresh cache)", [sys.executable, "-c", GENERATE], warm))
        for name, cache, label in (("eval, fresh cache (generation included)", fresh, "fresh"),
                                   ("eval, warm cache", warm, "warm")):
            out = Path(tmp) / f"run-{label}"
            rows.append(step(name, [*dyadbench, *MAIN_JOB, "--out", str(out)], cache))
            result = json.loads((out / "result.json").read_text())
            rows[-1].update(eval_wall_s=result["timing"]["wall_s"], turns=result["timing"]["turns"],
                            items=result["data"]["items"], metrics=result["metrics"])
    same = rows[1]["metrics"] == rows[2]["metrics"]
    write_result(args.out, render(rows, same), seed=0,
                 data={"rows": rows, "fresh_equals_warm": same, "command": " ".join(["dyadbench", *MAIN_JOB])})


def render(rows: list[dict], same: bool) -> str:
    lines = ["# The README main job end to end",
             "", f"`dyadbench {' '.join(MAIN_JOB)}` (default `--batch`; no `--threads`, so the threads the environment "
             f"sets: OMP_NUM_THREADS={os.environ.get('OMP_NUM_THREADS', 'unset')}), each step its own process.", "",
             "| step | wall (s) | CPU (s) | evaluation only (s) | load avg before → after |",
             "|---|---:|---:|---:|---|"]
    for r in rows:
        inner = f"{r['eval_wall_s']:.1f}" if "eval_wall_s" in r else "–"
        lines.append(f"| {r['step']} | {r['wall_s']:.1f} | {r['cpu_s']:.1f} | {inner} | "
                     f"{r['load_before']:.2f} → {r['load_after']:.2f} |")
    evals = [r for r in rows if "turns" in r]
    lines += ["", f"{evals[0]['items']} agents, {evals[0]['turns']} turns per eval; metrics of the fresh and the warm "
              f"run equal: {same}. \"Evaluation only\" is the result file's `timing.wall_s` (model build, "
              "streaming and scoring, after the split is open).", "",
              f"The machine ({os.cpu_count()} cores) was shared with other jobs (training and sweeps at higher "
              "priority; this ran under `nice -n 10`): the load averages above are the one-minute load, and every "
              "wall time is an upper bound for an idle machine. CPU (s) counts every thread of the command and its "
              "workers: with one thread, about the wall time the command would take with a core to itself."]
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    started = time.perf_counter()
    main()
    print(f"done in {time.perf_counter() - started:.0f} s")
