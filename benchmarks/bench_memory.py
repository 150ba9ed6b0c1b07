"""Peak memory of ``dyadbench eval`` and ``dyadbench score`` on the whole embedded test split and on a subset.

Each run is the real command in its own process, under a probe process that reads the command's
``getrusage(RUSAGE_CHILDREN).ru_maxrss`` (peak resident set, KiB on Linux: interpreter, libraries, data),
so every number is one command alone. The commands:

- **eval**: ``dyadbench eval --model mean-frame --dataset synthetic --split test --context 0 --clips N
  --threads 1 --out DIR`` (the v1 corpus, whose cache must exist; ``mean-frame`` costs nothing to stream,
  so the run is reading, writing and scoring); N = ``--small`` dialogues and the whole split.
- **eval, arrays held**: the same command with every direction's arrays kept until scoring, as ``eval`` did
  before it streamed its items (``dyadbench.protocol.runner.streams_items`` answering False in that
  process): the growth that streaming removes. Its metrics must equal the streamed run's.
- **score**: ``dyadbench score DIR/predictions --gt <cache>/synthetic-v1/test`` of each eval's predictions
  (the subset's predictions are scored against the whole split's ground truth, the others reported
  missing); its metrics must equal the eval's.
- **imports**: ``dyadbench models`` (the CLI's imports, no data): the floor.

Equal peaks at both sizes are what "streams clips and never holds a whole split" means; the held-arrays
runs show how the peak grew with the split before. One seed (0) everywhere; nothing else is random.

    nice -n 10 python benchmarks/bench_memory.py            # about 10 minutes on a busy two-core machine

Writes benchmarks/results/memory.{json,md} (``--out`` elsewhere).
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

from dyadbench.registry import DATASETS  # noqa: E402

#: Runs ``dyadbench ARGV`` in this process (optionally with eval holding every item's arrays), then exits.
COMMAND = """
import sys
from dyadbench.protocol import runner
if sys.argv[1] == "held":
    runner.streams_items = lambda suite: False
from dyadbench.cli import main
main(sys.argv[2:])
"""
#: Runs COMMAND as a child and prints the child's peak resident set (KiB) and its wall seconds.
PROBE = """
import resource, subprocess, sys, time
start = time.perf_counter()
subprocess.run([sys.executable, "-c", sys.argv[1], *sys.argv[2:]], check=True, stdout=subprocess.DEVNULL)
print(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss, time.perf_counter() - start)
"""


def measure(args: list[str], held: bool = False) -> dict:
    """Peak RSS (MiB) and wall seconds of ``dyadbench ARGS`` alone in its process."""
    out = subprocess.run([sys.executable, "-c", PROBE, COMMAND, "held" if held else "streamed", *args],
                         check=True, capture_output=True, text=True).stdout.split()
    return {"peak_mib": int(out[-2]) / 1024, "wall_s": float(out[-1])}


def metrics(path: Path) -> dict:
    result = json.loads(path.read_text())
    return {"metrics": result["metrics"], "items": result["data"]["items"]}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--small", type=int, default=20, help="dialogues of the subset")
    parser.add_argument("--clips", type=int, default=None, help="dialogues of the large run (default: the split)")
    parser.add_argument("--out", default=str(RESULTS / "memory"))
    args = parser.parse_args()
    os.environ["OMP_NUM_THREADS"] = "1"
    source = DATASETS.load("synthetic")(None, "test")
    total = len(source.clip_ids())
    sizes = [args.small, args.clips or total]
    rows = [{"command": "imports (dyadbench models)", "dialogues": 0, **measure(["models"])}]
    checks = []
    with tempfile.TemporaryDirectory(prefix="bench-memory-") as tmp:
        for n in sizes:
            runs = {}
            for mode in ("streamed", "held"):
                folder = Path(tmp) / f"{mode}{n}"
                cmd = ["eval", "--model", "mean-frame", "--dataset", "synthetic", "--split", "test", "--context", "0",
                       "--clips", str(n), "--threads", "1", "--seed", "0", "--out", str(folder)]
                rows.append({"command": "eval" + (", arrays held (before)" if mode == "held" else ""),
                             "dialogues": n, **measure(cmd, held=mode == "held")})
                runs[mode] = metrics(folder / "result.json")
                print(rows[-1], flush=True)
            score_dir = Path(tmp) / f"score{n}"
            rows.append({"command": "score", "dialogues": n,
                         **measure(["score", str(Path(tmp) / f"streamed{n}" / "predictions"), "--gt", str(source.root),
                                    "--seed", "0", "--out", str(score_dir)])})
            print(rows[-1], flush=True)
            scored = metrics(score_dir / "result.json")
            checks.append({"dialogues": n, "items": runs["streamed"]["items"],
                           "held_equal_streamed": runs["held"]["metrics"] == runs["streamed"]["metrics"],
                           "score_equal_eval": scored["metrics"] == runs["streamed"]["metrics"]})
    load = os.getloadavg()
    write_result(args.out, render(rows, checks, total, load), seed=0,
                 data={"rows": rows, "checks": checks, "split_dialogues": total, "load_average": list(load)})


def render(rows: list[dict], checks: list[dict], total: int, load: tuple[float, ...]) -> str:
    lines = ["# Peak memory of eval and score (synthetic v1 test split)", "",
             f"Each command alone in its process; peak resident set (ru_maxrss). The split has {total} dialogues "
             f"({2 * total} directions); model `mean-frame`, context 0, seed 0, one thread, one process.", "",
             "| command | dialogues | peak RSS (MiB) | wall (s) |", "|---|---:|---:|---:|"]
    lines += [f"| {r['command']} | {r['dialogues']} | {r['peak_mib']:.0f} | {r['wall_s']:.1f} |" for r in rows]
    lines += ["", "| dialogues | items | held-arrays metrics = streamed | score metrics = eval |",
              "|---:|---:|---|---|"]
    lines += [f"| {c['dialogues']} | {c['items']} | {c['held_equal_streamed']} | {c['score_equal_eval']} |"
              for c in checks]
    lines += ["", f"Load average at the end (1, 5, 15 min): {load[0]:.2f}, {load[1]:.2f}, {load[2]:.2f} on "
              f"{os.cpu_count()} cores: other jobs shared the machine, so wall times are upper bounds; peak "
              "memory does not depend on the load."]
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    started = time.perf_counter()
    main()
    print(f"done in {time.perf_counter() - started:.0f} s")
