"""TIMAR eval throughput today against the code before batched streaming existed (issue #23's "5× today's").

The baseline is the parent of the first commit that added ``predict_turns`` (``--old-rev``; default
:data:`OLD_REV`, found with ``git log --reverse -S predict_turns``). The script checks that revision out
into a temporary git worktree and runs, side by side in one run and each in its own process,

    dyadbench eval --model timar --dataset synthetic --split ood --context 7 --clips N --seed 0 [--jobs J]

with the old code (run from the worktree, so ``python -m dyadbench`` imports the worktree's package; checked
by printing ``dyadbench.__file__`` and ``models.__file__`` there, and by the ``environment.git`` commit each
result records) and with today's code (this checkout; default ``--batch``). Both score the same items (the
embedded v1 corpus, the old code's default, named explicitly): the prediction files of every run are compared
with the first run's (same names, largest |difference|), and so are the metrics (the recorded split digest is
not compared: its definition changed between the revisions). Configurations (``--configs``): ``old:1`` is
the command as the README gave it then (``--jobs 1``), ``new:2`` today's with ``--jobs 2``; ``old:2`` and
``new:1`` separate what the code gained from what two worker processes give.

Per run: the command's wall and CPU seconds (its workers included, ``benchmarks/bench_main_job.py``'s probe),
the result's own evaluation wall time (``timing.wall_s``: model build, streaming, scoring), the turns streamed,
turns per wall second, and the one-minute load average before and after. The corpus split is opened once
before any timed run (generated into the cache if missing), so no timed run pays generation. Every command
runs with ``OMP_NUM_THREADS=1`` (one thread per process) under this script's niceness.

    nice -n 10 python benchmarks/bench_eval_speedup.py      # writes benchmarks/results/eval_speedup.{json,md}
    python benchmarks/bench_eval_speedup.py --render        # the same file's text again from its recorded data
"""

from __future__ import annotations

import argparse
import json
import math
import os
import shlex
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from bench_main_job import PROBE  # noqa: E402  (benchmarks/bench_main_job.py: wall and CPU of a child command)
from output import RESULTS, ROOT, result_paths, write_result  # noqa: E402  (benchmarks/output.py)

#: Parent of f0bf24d ("Batched streaming: stream_agents ..."), the first commit with ``predict_turns``.
OLD_REV = "631f0681d2175cd35080f1ec3ceebc5de48f3163"
WHERE = "import dyadbench, models; print(dyadbench.__file__); print(models.__file__)"
#: The issue's throughput target (today's eval over the code before batching) and the profile that explains it.
TARGET = 5.0
PROFILE = RESULTS / "timar_profile.json"
OPEN_SPLIT = "from dyadbench.registry import DATASETS; DATASETS.load('synthetic')(None, 'ood')"


def eval_args(clips: int, jobs: int, out: Path) -> list[str]:
    return ["-m", "dyadbench", "eval", "--model", "timar", "--dataset", "synthetic", "--split", "ood",
            "--context", "7", "--clips", str(clips), "--seed", "0", "--jobs", str(jobs), "--out", str(out)]


def child_env() -> dict:
    """This environment with one thread per process and nothing that would put another checkout first."""
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    env["OMP_NUM_THREADS"] = "1"
    return env


def imported_from(cwd: Path) -> list[str]:
    """Files of the ``dyadbench`` and ``models`` packages a ``python`` started in ``cwd`` imports; refused
    unless both lie under ``cwd``."""
    files = subprocess.run([sys.executable, "-c", WHERE], cwd=cwd, env=child_env(), check=True,
                           capture_output=True, text=True).stdout.split()
    if not all(Path(f).resolve().is_relative_to(cwd.resolve()) for f in files):
        raise SystemExit(f"python in {cwd} imports {files}, not that checkout's packages")
    return files


def timed_eval(code: str, cwd: Path, clips: int, jobs: int, out: Path) -> dict:
    """Run one eval in ``cwd``; wall/CPU seconds, load before/after and what its result file records."""
    before = os.getloadavg()[0]
    probe = subprocess.run([sys.executable, "-c", PROBE, sys.executable, *eval_args(clips, jobs, out)], cwd=cwd,
                           env=child_env(), check=True, capture_output=True, text=True).stdout.split()
    result = json.loads((out / "result.json").read_text())
    row = {"code": code, "jobs": jobs, "wall_s": float(probe[-2]), "cpu_s": float(probe[-1]),
           "load_before": before, "load_after": os.getloadavg()[0], "eval_wall_s": result["timing"]["wall_s"],
           "turns": result["timing"]["turns"], "items": result["data"]["items"],
           "git": result["environment"].get("git"),
           "metrics": result["metrics"], "predictions": str(out / "predictions")}
    row["turns_per_s"] = row["turns"] / row["wall_s"]
    row["turns_per_cpu_s"] = row["turns"] / row["cpu_s"]
    print({k: v for k, v in row.items() if k not in ("metrics", "predictions")}, flush=True)
    return row


def metric_gap(a: dict, b: dict) -> float:
    """Largest |a − b| over the metrics both hold (NaN equal to NaN); inf when the keys differ."""
    if set(a) != set(b):
        return math.inf
    gaps = [0.0 if (x is None and y is None) or (isinstance(x, float) and isinstance(y, float) and math.isnan(x)
                                                  and math.isnan(y)) else abs(float(x) - float(y))
            for x, y in ((a[k], b[k]) for k in a)]
    return max(gaps, default=0.0)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--old-rev", default=OLD_REV, help="the baseline revision (default: before batching)")
    parser.add_argument("--clips", type=int, default=20,
                        help="first N dialogues of the v1 ood split (default: the README main job's 20)")
    parser.add_argument("--configs", default="old:1,new:2,old:2,new:1",
                        help="runs in order, code:jobs (code: old | new)")
    parser.add_argument("--out", default=str(RESULTS / "eval_speedup"))
    parser.add_argument("--render", action="store_true",
                        help="run nothing: write --out's tables again from the data it records (same command)")
    args = parser.parse_args()
    if args.render:
        return rerender(args.out)
    old_rev = subprocess.run(["git", "rev-parse", args.old_rev], cwd=ROOT, check=True, capture_output=True,
                             text=True).stdout.strip()
    new_rev = subprocess.run(["git", "rev-parse", "HEAD"], cwd=ROOT, check=True, capture_output=True,
                             text=True).stdout.strip()
    dirty = len(subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"], cwd=ROOT, check=True,
                               capture_output=True, text=True).stdout.splitlines())  # others' edits, if any
    subprocess.run([sys.executable, "-c", OPEN_SPLIT], cwd=ROOT, env=child_env(), check=True)
    rows = []
    with tempfile.TemporaryDirectory(prefix="bench-eval-speedup-") as tmp:
        worktree = Path(tmp) / "old"
        subprocess.run(["git", "worktree", "add", "--detach", str(worktree), old_rev], cwd=ROOT, check=True,
                       capture_output=True)
        try:
            where = {"old": imported_from(worktree), "new": imported_from(ROOT)}
            for i, config in enumerate(args.configs.split(",")):
                code, jobs = config.split(":")
                cwd = worktree if code == "old" else ROOT
                rows.append(timed_eval(code, cwd, args.clips, int(jobs), Path(tmp) / f"run{i}"))
            summary = compare(rows)
        finally:
            subprocess.run(["git", "worktree", "remove", "--force", str(worktree)], cwd=ROOT, check=True)
    for row in rows:  # old runs record the old revision; new ones this checkout's commit at the time (not the old)
        if row["git"] is not None and (row["git"] == old_rev) != (row["code"] == "old"):
            raise SystemExit(f"a {row['code']} run recorded commit {row['git']} (old revision {old_rev})")
    for row in rows:
        del row["predictions"]  # a temporary folder
    write_result(args.out, render(rows, summary, args, old_rev, where), seed=0,
                 data={"old_rev": old_rev, "new_rev": new_rev, "new_uncommitted_files": dirty, "clips": args.clips,
                       "rows": rows, "imported": where, **summary})


def prediction_gap(a: Path, b: Path) -> float:
    """Largest |difference| between two runs' predictions; inf unless they hold the same files and shapes."""
    names = sorted(p.name for p in a.glob("*.npy"))
    if not names or names != sorted(p.name for p in b.glob("*.npy")):
        return math.inf
    gaps = []
    for name in names:
        x, y = np.load(a / name), np.load(b / name)
        gaps.append(math.inf if x.shape != y.shape else float(np.abs(x.astype(np.float64) - y).max()))
    return max(gaps)


def rerender(out: str) -> None:
    """Write the result ``out`` again from its recorded data and command (this script's current text around the
    same numbers; nothing is run or measured)."""
    record = json.loads(result_paths(out)[0].read_text())
    data, command = record["data"], shlex.split(record["command"])[1:]  # [script, *args] as first run
    args = argparse.Namespace(clips=data["clips"])
    summary = {k: data[k] for k in ("ratios", "eval_ratios", "cpu_ratios", "same_turns", "max_prediction_gap",
                                    "max_metric_gap")}
    write_result(out, render(data["rows"], summary, args, data["old_rev"], data["imported"]), seed=record["seed"],
                 data=data, argv=[str(ROOT / command[0]), *command[1:]])


def compare(rows: list[dict]) -> dict:
    """Ratios (new over old) of turns per wall second of the command and of the evaluation alone, for every pair
    of runs, and how far each run's predictions and metrics are from the first run's."""
    pairs = [(n, o) for n in rows if n["code"] == "new" for o in rows if o["code"] == "old"]
    first = rows[0]
    return {"ratios": {f"new:{n['jobs']} / old:{o['jobs']}": n["turns_per_s"] / o["turns_per_s"] for n, o in pairs},
            "eval_ratios": {f"new:{n['jobs']} / old:{o['jobs']}": o["eval_wall_s"] / n["eval_wall_s"]
                            for n, o in pairs},
            "cpu_ratios": {f"new:{n['jobs']} / old:{o['jobs']}": n["turns_per_cpu_s"] / o["turns_per_cpu_s"]
                           for n, o in pairs},
            "same_turns": all(r["turns"] == first["turns"] and r["items"] == first["items"] for r in rows),
            "max_prediction_gap": max(prediction_gap(Path(first["predictions"]), Path(r["predictions"]))
                                      for r in rows),
            "max_metric_gap": max(metric_gap(first["metrics"], r["metrics"]) for r in rows)}


def render(rows: list[dict], summary: dict, args, old_rev: str, where: dict) -> str:
    lines = ["# TIMAR eval throughput: today against the code before batched streaming", "",
             f"`dyadbench eval --model timar --dataset synthetic --split ood --context 7 --clips {args.clips} "
             f"--seed 0 --jobs J` (default `--batch`), each run its own process with OMP_NUM_THREADS=1: old = "
             f"revision `{old_rev[:12]}` (the parent of the first commit with `predict_turns`, from a git "
             f"worktree; it imported `{where['old'][0]}` there), new = this checkout. Turns/s = turns streamed "
             "per wall second of the whole command (interpreter start, imports, model build, streaming and "
             "scoring); eval s = the result's own `timing.wall_s`.", "",
             "| code | jobs | wall s | CPU s | eval s | turns | turns/s | turns/CPU s | load avg before → after |",
             "|---|---:|---:|---:|---:|---:|---:|---:|---|"]
    for r in rows:
        lines.append(f"| {r['code']} | {r['jobs']} | {r['wall_s']:.1f} | {r['cpu_s']:.1f} | {r['eval_wall_s']:.1f} | "
                     f"{r['turns']} | {r['turns_per_s']:.1f} | {r['turns_per_cpu_s']:.1f} | "
                     f"{r['load_before']:.2f} → {r['load_after']:.2f} |")
    lines += ["", "| speed-up | whole command (turns/s) | evaluation only (eval s) | CPU (turns/CPU s) |",
              "|---|---:|---:|---:|"]
    lines += [f"| {k} | {v:.2f} | {summary['eval_ratios'][k]:.2f} | {summary['cpu_ratios'][k]:.2f} |"
              for k, v in summary["ratios"].items()]
    lines += ["", f"Same items in every run (predictions and turns): {summary['same_turns']}; largest |difference| "
              f"against the first run of any prediction: {summary['max_prediction_gap']:.3g}, of any metric: "
              f"{summary['max_metric_gap']:.3g}.", "",
              "Turns/CPU s counts the CPU time of the command and its workers: what the code costs, whatever the "
              "load; turns/s (wall) adds what two worker processes overlap, and is what a user waits for.", "",
              f"Load: the one-minute load average of the machine ({os.cpu_count()} cores) before and after each "
              "run, this benchmark's own processes included; with other work on the machine every time is an "
              "upper bound for an idle one, and the ratios, measured in the same run, are the numbers to read."]
    loads = [r[k] for r in rows for k in ("load_before", "load_after")]
    if sum(loads) / len(loads) >= (os.cpu_count() or 1):
        lines += ["", f"Here the load (mean {sum(loads) / len(loads):.1f}, lowest {min(loads):.1f}) exceeded the "
                  f"{os.cpu_count()} cores: a second "
                  "worker process found no free core, so the `--jobs 2` wall times measure contention rather than "
                  "the code, and the CPU ratios (the same items, bit for bit the same predictions) are the "
                  "comparable numbers."]
    headline = summary["ratios"].get("new:2 / old:1")
    if headline is not None and headline < TARGET:
        lines += ["", bound_note(summary)]
    return "\n".join(lines) + "\n"


def bound_note(summary: dict) -> str:
    """Why today's ``--jobs 2`` run stays under the target: the TIMAR per-turn profile (its committed result)."""
    key = "new:2 / old:1"
    headline, evaluation, cpu = (summary[k][key] for k in ("ratios", "eval_ratios", "cpu_ratios"))
    runs = {r["batch"]: r for r in json.loads(PROFILE.read_text())["data"]["runs"]}
    one, many = runs[1], runs[max(runs)]
    share = lambda r: r["ms_per_turn"]["encoder, sliding window"] / r["model_ms_per_turn"]  # noqa: E731
    gain = one["model_ms_per_turn"] / many["model_ms_per_turn"]
    same = summary["cpu_ratios"].get("new:1 / old:1")
    code = "" if same is None else f"; in one process each, {same:.2f}× in CPU per turn"
    return (f"**What bounds it** (today's `--jobs 2` against the old command: {headline:.2f}× on the whole command, "
            f"{evaluation:.2f}× on the evaluation alone, {cpu:.2f}× in CPU per turn{code}; the issue's target is "
            f"{TARGET:g}×). TIMAR at n = 7 spends {share(one):.0%} of a turn (batch 1; {share(many):.0%} at batch "
            f"{max(runs)}) re-encoding the sliding 8-turn window, a product over 880 rows per stream that a batch "
            "does not make cheaper (`benchmarks/results/timar_profile.md`): batching cuts the model's time per turn "
            f"from {one['model_ms_per_turn']:.2f} to {many['model_ms_per_turn']:.2f} ms ({gain:.2f}×), and two "
            f"worker processes on two cores give at most 2× in wall time, so about {2 * gain:.1f}× over today's code "
            "run one stream at a time in one process is all that batching and `--jobs 2` can give together, less "
            "what interpreter start, imports and scoring take, which neither changes. More needs less arithmetic "
            "per turn (that file's last section; the streaming-native `timar-stream` caches every turn exactly).")

if __name__ == "__main__":
    main()
