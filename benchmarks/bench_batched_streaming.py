"""Batched streaming: per-turn latency and throughput of each reference model at batch 1 and batched.

Streams a fixed subset of the embedded corpus (the first ``--clips`` dialogues of the ood split, both
directions; StyGazeTalk: the first ``--gaze-sessions`` sessions of the embedded gaze-head test split, by
default as many as the dialogues' directions, one direction each) through the
progressive-context protocol at n = 0, 3, 7, on one and on two CPU threads, one direction at a time
(``stream_agent``, batch 1: today's ``dyadbench eval``) and ``--batch`` directions together
(``stream_agents``), and prints per cell:

- throughput: turns streamed per wall-clock second, and the speed-up of the batched run over batch 1;
- latency: the mean wall-clock seconds of one model call (batch 1: one turn; batched: the turns of every
  open stream), i.e. how long a turn waits for its output;
- CPU seconds per turn (this process, all threads) and the largest |difference| between the batched and
  the batch-1 predictions (0 = bit for bit).

A batch-size sweep at n = 7 (one thread) of TIMAR (``--sweep-clips`` dialogues) and StyGazeTalk (as many
sessions as those dialogues' directions, at most the split's 8) shows where throughput levels off, which
sets ``dyadbench eval --batch``'s default. With ``--rss`` it also runs ``dyadbench eval``
(mean-frame) and ``dyadbench score`` on the whole embedded test split in child processes and reports their
peak resident memory (``resource.getrusage``).

    python benchmarks/bench_batched_streaming.py          # writes benchmarks/results/batched_streaming.{json,md}
"""

from __future__ import annotations

import argparse
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from dyadbench.protocol.config import ProtocolConfig  # noqa: E402
from dyadbench.protocol.interface import ModelOptions  # noqa: E402
from dyadbench.protocol.runner import build_model, set_threads  # noqa: E402
from dyadbench.protocol.streaming import stream_agent, stream_agents  # noqa: E402
from dyadbench.registry import DATASETS  # noqa: E402
from output import RESULTS, write_result  # noqa: E402  (benchmarks/output.py)

#: Reference model -> (dataset, split) it streams.
MODELS = {"timar": ("synthetic", "ood"), "timar-stream": ("synthetic", "ood"), "dualtalk": ("synthetic", "ood"),
          "sfms": ("synthetic", "ood"), "stygazetalk": ("synthetic-gaze", "test")}
CONTEXTS = (0, 3, 7)


def streams_of(name: str, dialogues: int, gaze_sessions: int | None = None) -> tuple[list[tuple], str]:
    """The directions ``name`` streams: ``dialogues`` dialogues' (both directions), or for a gaze-head model
    ``gaze_sessions`` sessions (default: as many as those dialogues' directions)."""
    dataset, split = MODELS[name]
    gaze = dataset == "synthetic-gaze"
    return directions(dataset, split, (gaze_sessions or 2 * dialogues) if gaze else dialogues)


def directions(dataset: str, split: str, clips: int) -> tuple[list[tuple], str]:
    source = DATASETS.load(dataset)(None, split)
    loaded = [source.load(clip_id) for clip_id in source.clip_ids()[:clips]]
    return [(clip, p.name) for clip in loaded for p in clip.agent_participants], loaded[0].layout


def run(name: str, dirs: list[tuple], layout: str, context: int, batch: int) -> dict:
    """Stream ``dirs`` once; wall, CPU, turns, calls and the predictions."""
    model = build_model(name, ModelOptions(extra={"layout": layout, "turn_seconds": 1.0}))
    config = ProtocolConfig(context=context)
    calls = 0
    if batch > 1:
        original = model.predict_turns

        def counted(turns):
            nonlocal calls
            calls += 1
            return original(turns)

        model.predict_turns = counted
    start, cpu = time.perf_counter(), time.process_time()
    if batch == 1:
        outs = [stream_agent(model, clip, agent, config) for clip, agent in dirs]
    else:
        outs = list(stream_agents(model, dirs, config, batch))
    wall, cpu = time.perf_counter() - start, time.process_time() - cpu
    turns = sum(o.num_turns for o in outs)
    return {"wall_s": wall, "cpu_s": cpu, "turns": turns, "calls": calls if batch > 1 else turns,
            "motion": [o.motion for o in outs]}


def cell(name: str, dirs: list[tuple], layout: str, context: int, threads: int, batch: int) -> dict:
    set_threads(threads)
    one, many = run(name, dirs, layout, context, 1), run(name, dirs, layout, context, batch)
    diff = max(float(np.abs(a.astype(np.float64) - b).max()) for a, b in zip(one["motion"], many["motion"]))
    row = {"model": name, "context": context, "threads": threads, "batch": batch, "turns": one["turns"],
           "max_abs_diff": diff}
    for key, r in (("b1", one), ("bN", many)):
        row[f"{key}_turns_per_s"] = r["turns"] / r["wall_s"]
        row[f"{key}_call_latency_ms"] = 1e3 * r["wall_s"] / r["calls"]
        row[f"{key}_cpu_ms_per_turn"] = 1e3 * r["cpu_s"] / r["turns"]
    row["speedup"] = row["bN_turns_per_s"] / row["b1_turns_per_s"]
    return row


def peak_rss(args: list[str]) -> tuple[float, float]:
    """(peak RSS in MiB, wall seconds) of ``dyadbench ARGS``, run under a child Python that reads its own
    child's ``getrusage`` (so each command is measured alone)."""
    probe = ("import resource, subprocess, sys; subprocess.run([sys.executable, '-m', 'dyadbench', *sys.argv[1:]], "
             "check=True, stdout=subprocess.DEVNULL); print(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss)")
    start = time.perf_counter()
    out = subprocess.run([sys.executable, "-c", probe, *args], check=True, capture_output=True, text=True).stdout
    return int(out.split()[-1]) / 1024, time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--clips", type=int, default=3, help="dialogues of each dialogue model's split")
    parser.add_argument("--gaze-sessions", type=int, default=None,
                        help="sessions of the gaze-head split (StyGazeTalk) [default: 2 x --clips]")
    parser.add_argument("--threads", default="1,2", help="CPU thread counts of the cells")
    parser.add_argument("--models", default=",".join(MODELS), help="reference models of the cells")
    parser.add_argument("--batch", type=int, default=16, help="batch of the batched runs")
    parser.add_argument("--sweep-clips", type=int, default=12, help="dialogues of the batch-size sweep")
    parser.add_argument("--sweep-models", default="timar,stygazetalk", help="models of the batch-size sweep")
    parser.add_argument("--sweep", default="1,4,8,16,24", help="batch sizes of the sweep")
    parser.add_argument("--rss", action="store_true", help="also measure peak RSS of eval and score (test split)")
    parser.add_argument("--out", default=str(RESULTS / "batched_streaming"))
    args = parser.parse_args()

    started_cpu, load_before = time.process_time(), os.getloadavg()[0]
    rows = []
    for name in args.models.split(","):
        dirs, layout = streams_of(name, args.clips, args.gaze_sessions)
        for threads in (int(t) for t in args.threads.split(",")):
            for context in CONTEXTS:
                rows.append(cell(name, dirs, layout, context, threads, args.batch))
                r = rows[-1]
                print(f"{name:13s} n={context} threads={threads}: {r['b1_turns_per_s']:7.1f} -> "
                      f"{r['bN_turns_per_s']:7.1f} turns/s (x{r['speedup']:.2f}), max|diff| {r['max_abs_diff']:.2g}",
                      flush=True)

    set_threads(1)
    sweep = []
    for name in args.sweep_models.split(","):
        dirs, layout = streams_of(name, args.sweep_clips)
        for batch in (int(b) for b in args.sweep.split(",")):
            r = run(name, dirs, layout, 7, batch)
            sweep.append({"model": name, "batch": batch, "streams": len(dirs), "turns": r["turns"],
                          "turns_per_s": r["turns"] / r["wall_s"], "call_latency_ms": 1e3 * r["wall_s"] / r["calls"],
                          "cpu_ms_per_turn": 1e3 * r["cpu_s"] / r["turns"]})
            print(f"{name} n=7 batch {batch}: {sweep[-1]['turns_per_s']:.1f} turns/s", flush=True)

    rss = {}
    if args.rss:
        with tempfile.TemporaryDirectory() as tmp:
            rss["eval"] = peak_rss(["eval", "--model", "mean-frame", "--split", "test", "--context", "7",
                                    "--threads", "1", "--out", f"{tmp}/eval"])
            source = DATASETS.load("synthetic")(None, "test")
            rss["score"] = peak_rss(["score", f"{tmp}/eval/predictions", "--gt", str(source.root)])
    cpu_total, load = time.process_time() - started_cpu, (load_before, os.getloadavg()[0])
    write_result(args.out, render(rows, sweep, rss, args, cpu_total, load), seed=0,
                 data={"cells": rows, "sweep": sweep, "rss_mib": rss, "cpu_s": cpu_total, "load_average_1min": load})


def render(rows: list[dict], sweep: list[dict], rss: dict, args, cpu_total: float,
           load: tuple[float, float]) -> str:
    lines = ["# Batched streaming: throughput and latency per reference model", "",
             f"Produced by `python benchmarks/bench_batched_streaming.py` (shipped tiny checkpoints, CPU). Subset: "
             f"the first {args.clips} dialogues of the embedded ood split, both directions (StyGazeTalk: the first "
             f"{args.gaze_sessions or 2 * args.clips} sessions of the embedded gaze-head test split, one direction "
             "each); batch 1 streams one direction at a "
             f"time (`stream_agent`, as `dyadbench eval --batch 1`), batch {args.batch} streams up to "
             f"{args.batch} directions together (`stream_agents`). Latency: mean wall-clock time of one model "
             "call (batch 1: one turn; batched: the turns of every open stream). max |diff|: largest difference "
             f"between the batched and the batch-1 predictions (0: bit for bit). Whole run: {cpu_total:.0f} CPU s "
             f"of this process, measured while model trainings shared the {os.cpu_count()} cores (one-minute load "
             f"average {load[0]:.2f} at the start, {load[1]:.2f} at the end), so absolute times are pessimistic "
             "and the ratios (and CPU ms per turn) are the numbers to read.", "",
             "| model | n | threads | turns | b1 turns/s | batched turns/s | speed-up | b1 latency ms | "
             "batched latency ms | b1 CPU ms/turn | batched CPU ms/turn | max abs diff |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['model']} | {r['context']} | {r['threads']} | {r['turns']} | {r['b1_turns_per_s']:.1f} | "
                     f"{r['bN_turns_per_s']:.1f} | {r['speedup']:.2f} | {r['b1_call_latency_ms']:.1f} | "
                     f"{r['bN_call_latency_ms']:.1f} | {r['b1_cpu_ms_per_turn']:.2f} | {r['bN_cpu_ms_per_turn']:.2f} | "
                     f"{r['max_abs_diff']:.2g} |")
    lines += ["", f"## Batch size (n = 7, one thread; TIMAR: first {args.sweep_clips} ood dialogues, both "
              "directions; StyGazeTalk: as many gaze-head test sessions, at most 8)", "",
              "| model | streams | batch | turns | turns/s | call latency ms | CPU ms/turn |",
              "|---|---|---|---|---|---|---|"]
    for s in sweep:
        lines.append(f"| {s['model']} | {s['streams']} | {s['batch']} | {s['turns']} | {s['turns_per_s']:.1f} | "
                     f"{s['call_latency_ms']:.1f} | {s['cpu_ms_per_turn']:.2f} |")
    if rss:
        lines += ["", "## Peak resident memory on the whole embedded test split", "",
                  "| command | peak RSS MiB | wall s |", "|---|---|---|"]
        for what, command in (("eval", "dyadbench eval --model mean-frame --split test --context 7"),
                              ("score", "dyadbench score PREDICTIONS --gt TEST_SPLIT")):
            lines.append(f"| `{command}` | {rss[what][0]:.0f} | {rss[what][1]:.0f} |")
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    main()
