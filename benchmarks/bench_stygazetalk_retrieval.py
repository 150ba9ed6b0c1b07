"""StyGazeTalk style encoders: does an embedding retrieve the right *speaker*, not the same session?

Protocol (cross-session speaker retrieval): non-overlapping 2-s windows (M = 50 frames) of the query
split are searched, by cosine top-1, among the windows of the gallery split, never among windows of the
query's own session; a hit is a window of the same speaker. The synthetic gaze corpus has 8 speakers, one
style each, jittered ±10 % per session (2 train, 1 val, 1 test session per speaker), so test -> train
and test -> val ask for the speaker across recordings. The within-session leave-one-out number over the
test windows (each speaker has one test session there) is printed beside it: it measures session identity.

References printed with it: the spread of the true style parameters between speakers and between one
speaker's sessions (what is achievable), and hand-made window statistics (angle std, mean |velocity|, rms
velocity, median |velocity|, left-right eye difference) z-scored on train, through the same protocol.

    python benchmarks/bench_stygazetalk_retrieval.py [--encoder PATH ...] [--out benchmarks/results/stygazetalk_retrieval.md]
"""

from __future__ import annotations

from pathlib import Path

import click
import numpy as np
import torch

from output import write_result  # benchmarks/output.py
from dyadbench.datasets.synthetic_gaze import SYNTHETIC_SEED
from dyadbench.registry import DATASETS
from dyadbench.synth.gaze import DEFAULT_SESSIONS, SPEAKERS, make_gaze_session
from models.stygazetalk.checkpoints import SHIPPED_STYLE_ENCODER, load_style_model
from models.stygazetalk.config import get_style_config
from models.stygazetalk.data import load_segments
from models.stygazetalk.train_style import retrieval_accuracy, tiled_windows

DATASET, WINDOW = "synthetic-gaze", 50
SESSIONS = {split: DEFAULT_SESSIONS[split] for split in ("train", "val", "test")}


def style_spread() -> tuple[float, float]:
    """Median over style parameters of the between-speaker and within-speaker (session) variance, both in
    units of the parameter's variance over all the sessions of SESSIONS."""
    rows = [make_gaze_session(split, i, SYNTHETIC_SEED, duration_s=1.0).meta
            for split, n in SESSIONS.items() for i in range(n)]
    names = [k for k in rows[0]["style"] if k != "sync"]
    p = np.array([[r["style"][k] for k in names] for r in rows])
    spk = np.array([r["speaker"] for r in rows])
    z = (p - p.mean(0)) / p.std(0)
    within = np.mean([z[spk == s].var(0, ddof=1) for s in SPEAKERS], axis=0)
    between = np.array([z[spk == s].mean(0) for s in SPEAKERS]).var(0, ddof=1)
    return float(np.median(between)), float(np.median(within))


def window_stats(w: np.ndarray) -> np.ndarray:
    v = np.diff(w, axis=1)
    lr = w[:, :, 3:5] - w[:, :, 5:7]
    return np.concatenate([w.std(1), np.abs(v).mean(1), np.sqrt((v ** 2).mean(1)), lr.mean(1),
                           np.diff(lr, axis=1).std(1), np.median(np.abs(v), axis=1)], axis=1)


def protocols(embed, windows) -> dict[str, tuple[float, float]]:
    e = {s: embed(w[0]) for s, w in windows.items()}
    out = {"test LOO (same session allowed)": retrieval_accuracy(e["test"], windows["test"][1])}
    for q, g in (("test", "train"), ("test", "val"), ("val", "train")):
        out[f"{q} -> {g}"] = retrieval_accuracy(e[q], windows[q][1], e[g], windows[g][1],
                                                q_sessions=windows[q][2], g_sessions=windows[g][2])
    return out


@click.command()
@click.option("--encoder", "encoders", multiple=True, type=click.Path(dir_okay=False, path_type=Path),
              help="Stage-1 checkpoints to compare (default: the shipped evaluator).")
@click.option("--out", type=click.Path(dir_okay=False, path_type=Path),
              default=Path("benchmarks/results/stygazetalk_retrieval.md"), show_default=True)
def main(encoders: tuple[Path, ...], out: Path) -> None:
    torch.set_num_threads(1)
    limit = get_style_config("tiny-se64").angle_limit_deg
    segs = {s: load_segments(DATASETS.load(DATASET)(None, s), limit, WINDOW) for s in SESSIONS}
    windows = {s: tiled_windows(seg, WINDOW) for s, seg in segs.items()}
    ref = window_stats(windows["train"][0])
    rows = {"hand-made window statistics": protocols(
        lambda w: (window_stats(w) - ref.mean(0)) / ref.std(0), windows)}
    for path in encoders or (SHIPPED_STYLE_ENCODER,):
        model, meta = load_style_model(path)
        c = model.cfg
        label = (f"{path.name} ({c.name}; inputs {c.input_features}, positives {c.positives}, negatives "
                 f"{c.negatives}, dropout {c.dropout}, {c.steps} steps)")
        rows[label] = protocols(model.embed_degrees, windows)
    between, within = style_spread()
    cols = list(next(iter(rows.values())))
    lines = ["# StyGazeTalk style retrieval: speaker across sessions", "",
             "Produced by `python benchmarks/bench_stygazetalk_retrieval.py` (see its docstring for the protocol; "
             f"embedded `{DATASET}` sessions, non-overlapping {WINDOW}-frame windows, cosine top-1; cells are "
             "accuracy / chance).", "",
             f"True style parameters (median over the 13 jittered parameters, variance in units of the variance "
             f"over all {sum(SESSIONS.values())} sessions): between speakers {between:.3f}, "
             f"between one speaker's sessions {within:.3f} "
             f"(ratio {between / within:.1f}); the session jitter does not swamp the speakers.", "",
             "| embedding | " + " | ".join(cols) + " |", "|---" * (len(cols) + 1) + "|"]
    for name, res in rows.items():
        lines.append(f"| {name} | " + " | ".join(f"{a:.3f} / {ch:.3f}" for a, ch in res.values()) + " |")
    text = "\n".join(lines) + "\n"
    click.echo(text)
    write_result(out, text, seed=SYNTHETIC_SEED)


if __name__ == "__main__":
    main()
