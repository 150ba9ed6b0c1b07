"""Where TIMAR's per-turn time goes at n = 7, at batch 1 and batched: why batching gains little there.

Streams the first ``--clips`` dialogues of the embedded ood split (both directions) through ``timar``
(shipped tiny checkpoint, one thread, context 7) with ``stream_agent`` (batch 1) and with ``stream_agents``
(``--batch`` directions together), and times, inside the model, each part of a turn by wrapping the
instance's methods (the model's code is not changed):

- **speech features**: the frontend's features of the turn's waveforms (``frontend.features``);
- **tokens**: the turn tokens from features and partner motion (``model.turn_tokens``);
- **encoder, cached turn**: one new turn against the cached keys/values while the window still grows
  (turns 0..n, ``model.encode_next_turn``);
- **encoder, sliding window**: the whole (n + 1)-turn window re-encoded once it slides (turns > n,
  ``model.encode``): positions are window-indexed, so no cached key/value stays valid;
- **diffusion head**: the head's denoising steps for the turn's frames (``model.sample_frames``);
- **other**: the rest of ``predict_turns`` (grouping, copies, caches).

Each part is reported as milliseconds per turn (wall clock of the calls divided by the turns streamed) and as
a share of the model's time, at batch 1 and batched. Seed 0 (the protocol's), outputs not compared here
(``tests/test_batched_streaming.py`` does). The machine is shared with other jobs: absolute times are upper
bounds; the shares and the batch-1/batched ratios are the numbers to read.

    nice -n 10 python benchmarks/bench_timar_profile.py

Writes benchmarks/results/timar_profile.{json,md} (``--out`` elsewhere).
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from collections import defaultdict
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from dyadbench.protocol.config import ProtocolConfig  # noqa: E402
from dyadbench.protocol.interface import ModelOptions  # noqa: E402
from dyadbench.protocol.runner import build_model, set_threads  # noqa: E402
from dyadbench.protocol.streaming import stream_agent, stream_agents  # noqa: E402
from dyadbench.registry import DATASETS  # noqa: E402
from output import RESULTS, write_result  # noqa: E402  (benchmarks/output.py)

PARTS = {"speech features": ("frontend", "features"), "tokens": ("model", "turn_tokens"),
         "encoder, cached turn": ("model", "encode_next_turn"), "encoder, sliding window": ("model", "encode"),
         "diffusion head": ("model", "sample_frames")}


def instrument(model, seconds: dict[str, float], calls: dict[str, int]) -> None:
    """Wrap the parts of :data:`PARTS` on this model instance so each call adds its wall time to ``seconds``."""
    for part, (owner, name) in PARTS.items():
        target = getattr(model, owner)
        inner = getattr(target, name)

        def timed(*args, _inner=inner, _part=part, **kwargs):
            start = time.perf_counter()
            try:
                return _inner(*args, **kwargs)
            finally:
                seconds[_part] += time.perf_counter() - start
                calls[_part] += 1
        setattr(target, name, timed)


def profile(dirs: list[tuple], layout: str, context: int, batch: int) -> dict:
    model = build_model("timar", ModelOptions(extra={"layout": layout, "turn_seconds": 1.0}))
    seconds: dict[str, float] = defaultdict(float)
    calls: dict[str, int] = defaultdict(int)
    instrument(model, seconds, calls)
    config = ProtocolConfig(context=context)
    start = time.perf_counter()
    if batch == 1:
        outs = [stream_agent(model, clip, agent, config) for clip, agent in dirs]
    else:
        outs = list(stream_agents(model, dirs, config, batch))
    wall = time.perf_counter() - start
    turns = sum(o.num_turns for o in outs)
    model_s = sum(sum(o.turn_latency_s) for o in outs)
    parts = {p: 1e3 * seconds[p] / turns for p in PARTS}
    parts["other"] = 1e3 * model_s / turns - sum(parts.values())
    return {"batch": batch, "turns": turns, "wall_s": wall, "model_ms_per_turn": 1e3 * model_s / turns,
            "ms_per_turn": parts, "calls": dict(calls),
            "diffusion_steps": int(len(model.model.sample_diffusion.timestep_map)), "depth": model.model.cfg.depth,
            "tokens_per_turn": model.model.cfg.tokens_per_turn}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--clips", type=int, default=4, help="dialogues of the ood split (both directions)")
    parser.add_argument("--batch", type=int, default=8)
    parser.add_argument("--context", type=int, default=7)
    parser.add_argument("--out", default=str(RESULTS / "timar_profile"))
    args = parser.parse_args()
    set_threads(1)
    source = DATASETS.load("synthetic")(None, "ood")
    clips = [source.load(c) for c in source.clip_ids()[:args.clips]]
    dirs = [(clip, p.name) for clip in clips for p in clip.agent_participants]
    runs = [profile(dirs, clips[0].layout, args.context, b) for b in (1, args.batch)]
    for r in runs:
        print(r, flush=True)
    load = os.getloadavg()
    write_result(args.out, render(runs, args, load), seed=0, data={"runs": runs, "load_average": list(load)})


def render(runs: list[dict], args, load) -> str:
    one, many = runs
    lines = [f"# TIMAR per-turn cost at n = {args.context} (shipped tiny checkpoint, one thread)", "",
             f"The first {args.clips} dialogues of the embedded (v1) ood split, both directions "
             f"({one['turns']} turns); batch 1 and batch {args.batch}. {one['diffusion_steps']} diffusion sampling "
             "steps per turn.", "",
             f"| part | batch 1 ms/turn | share | batch {args.batch} ms/turn | share | batch-1 / batched |",
             "|---|---:|---:|---:|---:|---:|"]
    for part in [*PARTS, "other"]:
        a, b = one["ms_per_turn"][part], many["ms_per_turn"][part]
        ratio = f"{a / b:.2f}" if b > 0 else "–"
        lines.append(f"| {part} | {a:.2f} | {a / one['model_ms_per_turn']:.0%} | {b:.2f} | "
                     f"{b / many['model_ms_per_turn']:.0%} | {ratio} |")
    lines.append(f"| **model total** | {one['model_ms_per_turn']:.2f} | 100% | {many['model_ms_per_turn']:.2f} | "
                 f"100% | {one['model_ms_per_turn'] / many['model_ms_per_turn']:.2f} |")
    n, depth, length = args.context, one["depth"], one["tokens_per_turn"]
    window = one["ms_per_turn"]["encoder, sliding window"] / one["model_ms_per_turn"]
    last_layer = (n / (n + 1)) / depth  # share of the re-encode's attention and feed-forward rows skippable
    lines += ["", "Calls (batch 1 / batched): " + "; ".join(
        f"{p} {one['calls'].get(p, 0)} / {many['calls'].get(p, 0)}" for p in PARTS), "",
        f"**Why batching gains little at n = {n}.** Once the window slides (turn > n), faithful TIMAR re-encodes "
        f"the whole window of {n + 1} turns × {length} tokens through its {depth} layers every turn: "
        f"{window:.0%} of the model's time at batch 1. That work is already a matrix product over "
        f"{(n + 1) * length} rows per stream, so putting several streams in one call adds rows to a product that "
        "is compute-bound, not call-bound: the re-encode's cost per turn stays the same (ratio about 1 above). "
        "Batching pays where calls are small: the diffusion head (one turn's frames, "
        f"{one['diffusion_steps']} steps), the tokens and the cached turns; they are the rest of the time, "
        f"which bounds the gain at n = {n} (here {one['model_ms_per_turn'] / many['model_ms_per_turn']:.2f}× in "
        "model time); at n = 0 there is no re-encode, which is why it gains most.",
        "",
        "**What an exact speed-up would need.** Less arithmetic per turn, not larger batches. Nothing of the old "
        "window can be reused: positions are window-indexed and added before the first layer, so after a slide "
        "every row's input changes (which is why the cache holds only while the window grows). What can go: in "
        f"the last layer only the current turn's {length} queries feed the head, so computing that layer's "
        f"attention and feed-forward for those rows only (keys and values still for all) removes about "
        f"(n/(n+1))/depth = {last_layer:.0%} of the re-encode's attention and feed-forward work, equal up to float "
        "rounding. Beyond that the model itself must change: `timar-stream` (per-turn band, relative turn "
        "offsets) caches every turn's keys and values exactly, so each turn encodes only its own tokens against "
        "the cached band (`benchmarks/results/batched_streaming.md`: its n = 7 throughput stays near its n = 0)."]
    lines += ["",
        f"Load average at the end (1, 5, 15 min): {load[0]:.2f}, {load[1]:.2f}, {load[2]:.2f} on {os.cpu_count()} "
        "cores (other jobs running): absolute times are upper bounds."]
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    main()
