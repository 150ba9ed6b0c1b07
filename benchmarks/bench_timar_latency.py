"""Per-turn latency of TIMAR and TIMAR-stream through the streaming protocol, with and without the cache.

Streams synthetic test clips (both directions) at contexts n = 0, 3, 7 for each model and cache
setting and prints the mean and median per-turn latency (the protocol's timing of ``predict_turn``),
the real-time factor (latency / turn length; < 1 streams faster than real time) and the speed-up over
the reference approach, the faithful model re-encoding every window (the released design, no cache).
Cached and uncached outputs of the same model and seed are also compared (max |difference|).

    python benchmarks/bench_timar_latency.py                 # shipped tiny checkpoints, CPU
    python benchmarks/bench_timar_latency.py --config large --device cuda   # random weights, GPU

Writes benchmarks/results/timar_latency.{json,md} (``--out`` elsewhere).
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
from pathlib import Path

import numpy as np
import torch

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from dyadbench.protocol.config import ProtocolConfig  # noqa: E402
from dyadbench.protocol.interface import ModelOptions  # noqa: E402
from dyadbench.protocol.streaming import stream_agent  # noqa: E402
from dyadbench.synth.corpus import make_clips  # noqa: E402
from dyadbench.training.checkpoint import save_checkpoint  # noqa: E402
from models.timar.config import preset  # noqa: E402
from models.timar.model import TimarModel  # noqa: E402
from models.timar.registry import build_timar, build_timar_stream  # noqa: E402
from output import RESULTS, Transcript, preformatted, write_result  # noqa: E402  (benchmarks/output.py)

BUILDERS = {"timar": (build_timar, "faithful"), "timar-stream": (build_timar_stream, "stream")}


def random_checkpoint(name: str, config: str, folder: Path) -> Path:
    """Untrained weights of a configuration (latency does not depend on the weights' values)."""
    cfg = preset(config, BUILDERS[name][1])
    torch.manual_seed(0)
    model = TimarModel(cfg)
    with torch.no_grad():  # the head's output layers start at zero; make outputs depend on the inputs
        for p in model.head.parameters():
            p.add_(torch.randn_like(p) * 0.02)
    path = folder / f"{name}-{config}-random.pt"
    save_checkpoint(path, model_state=model.state_dict(), config=cfg.to_dict(), meta={"model": name})
    return path


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--config", default=None,
                        help="Use untrained weights of this config (tiny/base/large/huge) instead of the shipped ones.")
    parser.add_argument("--clips", type=int, default=2, help="Synthetic test clips to stream (both directions).")
    parser.add_argument("--seconds", type=float, default=30.0, help="Length of each clip in seconds.")
    parser.add_argument("--contexts", default="0,3,7", help="Comma-separated history lengths n.")
    parser.add_argument("--device", default="cpu")
    parser.add_argument("--threads", type=int, default=1, help="torch CPU threads.")
    parser.add_argument("--out", type=Path, default=RESULTS / "timar_latency", help="Result to write (.json and .md).")
    args = parser.parse_args()
    torch.set_num_threads(args.threads)
    clips = make_clips("test", args.clips, duration_s=args.seconds)
    contexts = [int(c) for c in args.contexts.split(",")]
    tmp = Path(tempfile.mkdtemp(prefix="timar-bench-"))
    weights = {name: random_checkpoint(name, args.config, tmp) if args.config else None for name in BUILDERS}

    rows, outputs = {}, {}
    for name, (build, _) in BUILDERS.items():
        for cache in (True, False):
            model = build(ModelOptions(weights=weights[name], device=args.device, extra={"cache": cache}))
            for n in contexts:
                config = ProtocolConfig(context=n)
                lat, motion = [], []
                for clip in clips:
                    for p in clip.participants:
                        out = stream_agent(model, clip, p.name, config)
                        lat.extend(out.turn_latency_s)
                        motion.append(out.motion)
                rows[name, cache, n] = (statistics.mean(lat), statistics.median(lat), len(lat))
                outputs[name, cache, n] = np.concatenate(motion)

    say = (transcript := Transcript()).say
    cfg_name = args.config or "tiny (shipped)"
    say(f"TIMAR per-turn latency, config {cfg_name}, device {args.device}, {args.threads} thread(s), "
        f"{len(clips)} clips x {args.seconds:.0f} s, both directions; turn = 1 s")
    say(f"{'model':<13} {'cache':<5} {'n':>2} {'mean ms':>9} {'median ms':>10} {'RTF':>7} "
        f"{'speed-up':>9} {'turns':>6} {'max|cached-uncached|':>21}")
    for (name, cache, n), (mean, median, turns) in rows.items():
        reference = rows["timar", False, n][1]
        diff = np.abs(outputs[name, True, n] - outputs[name, False, n]).max()
        say(f"{name:<13} {'yes' if cache else 'no':<5} {n:>2} {mean * 1e3:9.2f} {median * 1e3:10.2f} "
            f"{mean / 1.0:7.4f} {reference / median:8.2f}x {turns:6d} {diff:21.2e}")
    say("RTF = mean latency / 1-s turn; speed-up = median latency of timar without cache / this row's median")
    for n in contexts:
        stream = rows["timar-stream", True, n]
        say(f"n={n}: timar-stream (cache) is {rows['timar', True, n][1] / stream[1]:.2f}x faster per turn (median) "
            f"than timar (cache) and {rows['timar', False, n][1] / stream[1]:.2f}x than timar re-encoding")
    text = preformatted("TIMAR per-turn latency through the streaming protocol", transcript.text())
    print("wrote", *write_result(args.out, text, seed=0))


if __name__ == "__main__":
    main()
