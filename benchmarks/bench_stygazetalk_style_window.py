"""StyGazeTalk's training style window: the literal reading (D7) against the leak-free one, and style transfer.

In training, the literal reading computes s = SE(the motion-input window x_{u−1..u+M−2}), which holds M−1 of
the M target frames; at inference s = SE(the M most recent known frames), which holds none of the frames
being generated. The leak-free option (``style_input="past"``) reads the M frames just before the first
scored target (x_{u−M..u−1} with the loss on all M outputs), so training sees the style as inference does.

Both arms are the tiny SE-64 preset (λ = 1, the spec's validation-loss selection, mean decoding) with the
shipped SE-64 style encoder, trained on the same windows (every bank row holds the M − 1 frames of history
the leak-free window needs, so both arms' windows start at u ≥ M), seeds 0..S−1, with the preset's 1,500 steps
(``--steps`` to change it). Each checkpoint is streamed over the synthetic test sessions
(n = 7) and scored with the gaze–head suite (the 50-frame seed window excluded); the table gives mean ± s.e.
over seeds and the paired per-seed difference (leak-free − literal).

Style transfer: each test session A is generated again with the style vector of speaker B's first train
session (``reference_style``: mean SE over its windows) for every other speaker B. Session-level style
distance, with ū_X the mean of the unit-normalised evaluator embeddings of X's windows (M, hop N, after the
seed window):

    CE(X, Y) = mean over window pairs (i of X, j of Y) of 1 − cos(e_i, e_j) = 1 − ū_X · ū_Y

"CE to B" compares the output with B's ground-truth test session, "CE to A" with A's. Per session A
(mean over the 7 references and the seeds), the paired tests over the 8 sessions are Wilcoxon signed-rank
and paired t: transfer output CE to B vs CE to A; CE to B with transfer vs without; and (CE to B − CE to A)
with transfer vs without (what the transfer changes, net of how far A's and B's ground truths lie apart).

    python benchmarks/bench_stygazetalk_style_window.py --seeds 3 --jobs 2
Writes benchmarks/results/stygazetalk_style_window.{json,md}.
"""

from __future__ import annotations

import math
import sys
from concurrent.futures import ProcessPoolExecutor
from dataclasses import replace
from pathlib import Path

import click
import numpy as np
import torch
from scipy import stats

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_stygazetalk_variants import stream_items  # noqa: E402  (benchmarks/bench_stygazetalk_variants.py)
from output import write_result  # noqa: E402  (benchmarks/output.py)
from seed_stats import mean_se  # noqa: E402  (benchmarks/seed_stats.py)
from dyadbench.metrics.gaze import sliding_windows  # noqa: E402
from dyadbench.protocol.config import ProtocolConfig  # noqa: E402
from dyadbench.protocol.interface import ModelOptions  # noqa: E402
from dyadbench.registry import DATASETS  # noqa: E402
from dyadbench.scoring.gaze import SEED_FRAMES, score_arrays  # noqa: E402
from dyadbench.scoring.report import ScoreItem  # noqa: E402
from models.stygazetalk.checkpoints import (SHIPPED_STYLE_ENCODER, load_style_model, load_system,  # noqa: E402
                                            save_system, system_from_style)
from models.stygazetalk.config import get_generator_config  # noqa: E402
from models.stygazetalk.data import load_segments  # noqa: E402
from models.stygazetalk.evaluator import load_style_evaluator  # noqa: E402
from models.stygazetalk.generation import generate_session  # noqa: E402
from models.stygazetalk.train_generator import train_generator  # noqa: E402

DATASET = "synthetic-gaze"
PRESET = "tiny-se64"
ARMS = (("motion-window", "literal (D7: SE reads the motion inputs)"),
        ("past", "leak-free (SE reads the M frames before the targets)"))
COLUMNS = (("sim_gt", "SimWithGT↑"), ("sim_gt_seq", "Sim_seq↑"), ("style_ce", "CE↓"), ("mae_all", "All MAE↓"),
           ("vel_all", "All Vel↓"), ("mee_all", "All MEE↓"), ("fix_ratio", "FixRatio"), ("comp_score", "CompScore"),
           ("bas_delta_head", "Head ΔBAS↑"))


def train_arm(style_input: str, seed: int, steps: int, out: Path) -> dict:
    """Train one generator of the comparison (tiny SE-64, the shipped style encoder) and save it to ``out``."""
    style, _ = load_style_model(SHIPPED_STYLE_ENCODER)
    cfg = replace(get_generator_config(PRESET), style_input=style_input, seed=seed, steps=steps,
                  val_every=min(250, steps)).validate()
    history = cfg.window - 1  # the leak-free window's history, for both arms: the same training windows
    system = system_from_style(cfg, style)
    train_src, val_src = (DATASETS.load(DATASET)(None, split) for split in ("train", "val"))
    train = load_segments(train_src, cfg.angle_limit_deg, cfg.window + 1 + history)
    val = load_segments(val_src, cfg.angle_limit_deg, cfg.window + 1 + history)
    log = train_generator(system, train, val, progress=False, history=history)
    meta = {"data": {"train": train_src.describe(), "val": val_src.describe()}, "seed": seed, "steps": steps,
            "history": history, "best_step": log.best_step, "best_val_loss": log.best_val,
            "train_seconds": log.seconds, "train_windows": log.train_windows, "curve": log.curve()}
    save_system(out, system, meta)
    return meta


def _stream(weights: Path, clips, config: ProtocolConfig) -> list[ScoreItem]:
    return stream_items("stygazetalk", ModelOptions(weights=weights, extra={"decoding": "mean"}), clips, config)


def session_style(evaluator, motion: np.ndarray) -> np.ndarray:
    """ū: the mean of the unit-normalised evaluator embeddings of the windows after the seed window."""
    e = evaluator(sliding_windows(np.asarray(motion[SEED_FRAMES:], np.float64), evaluator.window, evaluator.hop))
    return (e / np.linalg.norm(e, axis=1, keepdims=True)).mean(axis=0)


def session_ce(u: np.ndarray, v: np.ndarray) -> float:
    """CE(X, Y) = 1 − ū_X · ū_Y: the mean over all window pairs of the style cosine error."""
    return float(1.0 - u @ v)


def transfer(weights: Path, clips, references: dict[str, np.ndarray], gt_styles: list[np.ndarray],
             evaluator) -> dict[str, np.ndarray]:
    """Per test session A: CE to A and to B of the output without transfer, and (mean over references B of
    the other speakers) with B's reference style."""
    system, _ = load_system(weights)
    system.cfg = replace(system.cfg, decoding="mean")
    out = {k: np.zeros(len(clips)) for k in ("own_to_A", "own_to_B", "transfer_to_A", "transfer_to_B")}
    speakers = [c.participants[0].identity for c in clips]
    styles = {spk: system.reference_style(ref) for spk, ref in references.items()}
    for i, clip in enumerate(clips):
        p = clip.participants[0]
        n = p.motion.shape[0]
        own = session_style(evaluator, generate_session(system, p.audio, p.motion[:SEED_FRAMES], n))
        others = [j for j in range(len(clips)) if speakers[j] != speakers[i]]
        out["own_to_A"][i] = session_ce(own, gt_styles[i])
        out["own_to_B"][i] = np.mean([session_ce(own, gt_styles[j]) for j in others])
        to_a, to_b = [], []
        for j in others:
            moved = session_style(evaluator, generate_session(system, p.audio, p.motion[:SEED_FRAMES], n,
                                                              style=styles[speakers[j]]))
            to_a.append(session_ce(moved, gt_styles[i]))
            to_b.append(session_ce(moved, gt_styles[j]))
        out["transfer_to_A"][i], out["transfer_to_B"][i] = np.mean(to_a), np.mean(to_b)
    return out


def paired_tests(x: np.ndarray, y: np.ndarray) -> dict:
    """x − y over sessions: mean, s.e., sessions with x < y, Wilcoxon signed-rank and paired t p-values."""
    d = np.asarray(x) - np.asarray(y)
    return {"mean": float(d.mean()), "se": float(d.std(ddof=1) / math.sqrt(len(d))), "lower": int((d < 0).sum()),
            "n": len(d), "wilcoxon_p": float(stats.wilcoxon(d).pvalue), "t_p": float(stats.ttest_rel(x, y).pvalue)}


def _mean_se(values: list[float]) -> str:
    return "{:.3f} ± {:.3f}".format(*mean_se(values))


def _context_of_run(context: int):
    """Test clips, protocol config, evaluator, ground-truth session styles and each speaker's reference
    (its first train session), as every run reads them."""
    clips = list(DATASETS.load(DATASET)(None, "test"))
    evaluator = load_style_evaluator()
    gt_styles = [session_style(evaluator, c.participants[0].motion) for c in clips]
    references = {}
    for clip in DATASETS.load(DATASET)(None, "train"):
        p = clip.participants[0]
        references.setdefault(p.identity, np.asarray(p.motion, np.float32))
    return clips, ProtocolConfig(context=context, seed=0), evaluator, gt_styles, references


def run_arm(style_input: str, seed: int, steps: int, path: Path, reuse: bool, context: int) -> dict:
    """Train (unless --reuse finds the checkpoint), stream, score and test style transfer for one arm/seed."""
    torch.set_num_threads(1)
    clips, config, evaluator, gt_styles, references = _context_of_run(context)
    meta = load_system(path)[1] if reuse and path.is_file() else train_arm(style_input, seed, steps, path)
    metrics = score_arrays(_stream(path, clips, config), seed=0, style_encoder=evaluator).metrics
    moved = transfer(path, clips, references, gt_styles, evaluator)
    return {"seed": seed, "best_step": meta["best_step"], "best_val_loss": meta["best_val_loss"],
            "train_seconds": meta["train_seconds"], "train_windows": meta["train_windows"],
            "metrics": {k: float(metrics[k]) for k, _ in COLUMNS},
            "transfer": {k: v.tolist() for k, v in moved.items()}}


@click.command()
@click.option("--seeds", type=click.IntRange(min=2), default=3, show_default=True, help="Seeds 0..S-1 per arm.")
@click.option("--steps", type=click.IntRange(min=1), default=1500, show_default=True,
              help="Training steps per generator (the tiny preset's 1,500 by default).")
@click.option("--work", type=click.Path(file_okay=False, path_type=Path), default=Path("runs/stygazetalk-style-window"),
              show_default=True, help="Folder for the trained checkpoints.")
@click.option("--reuse", is_flag=True, help="Re-use checkpoints already in --work instead of retraining.")
@click.option("--jobs", type=click.IntRange(min=1), default=1, show_default=True,
              help="Processes (one arm and seed each); results do not depend on it.")
@click.option("--context", default=7, show_default=True, help="Protocol context n (history turns).")
@click.option("--out", type=click.Path(dir_okay=False, path_type=Path),
              default=Path(__file__).parent / "results" / "stygazetalk_style_window.md", show_default=True)
def main(seeds: int, steps: int, work: Path, reuse: bool, jobs: int, context: int, out: Path) -> None:
    """Train, stream and score both style windows over seeds, then the style-transfer test; write the table."""
    torch.set_num_threads(1)
    work.mkdir(parents=True, exist_ok=True)
    seed_list = list(range(seeds))
    clips, _, evaluator, gt_styles, _ = _context_of_run(context)
    data: dict = {"preset": PRESET, "steps": steps, "seeds": seed_list, "context": context,
                  "evaluator": {"version": evaluator.version, "sha256": evaluator.digest}, "arms": {}}
    todo = [(style_input, seed, steps, work / f"{PRESET}-{style_input}-steps{steps}-seed{seed}.pt", reuse, context)
            for style_input, _ in ARMS for seed in seed_list]
    with ProcessPoolExecutor(jobs) as pool:
        futures = [pool.submit(run_arm, *args) for args in todo]
        for args, future in zip(todo, futures):
            data["arms"].setdefault(args[0], {"runs": []})["runs"].append(future.result())
    gt = score_arrays([ScoreItem(f"{c.clip_id}_{c.participants[0].name}", c.participants[0].motion,
                                 c.participants[0].motion, audio=c.participants[0].audio,
                                 identity=c.participants[0].identity) for c in clips],
                      seed=0, style_encoder=evaluator).metrics
    text = _markdown(data, gt, gt_styles, clips, seeds, steps, context)
    click.echo(text)
    write_result(out, text, seed=seed_list, data=data)


def _markdown(data: dict, gt: dict, gt_styles, clips, seeds: int, steps: int, context: int) -> str:
    arms = data["arms"]
    lines = ["# StyGazeTalk: literal vs leak-free training style window, and style transfer", "",
             f"Command: `python benchmarks/bench_stygazetalk_style_window.py --seeds {seeds} --steps {steps}`. "
             f"{PRESET} generators (λ = 1, validation-loss selection, mean decoding) with the shipped SE-64 style "
             f"encoder; {steps} training steps each" + ("" if steps == 1500 else " (the preset trains 1,500)") + ", "
             f"seeds 0–{seeds - 1}, both arms on the same training windows; streamed over the {len(clips)} "
             f"synthetic test sessions (n = {context}, the 50-frame seed window excluded); CE uses evaluator "
             f"{data['evaluator']['version']} (sha256 {data['evaluator']['sha256'][:12]}…). Mean ± s.e. over seeds.",
             "", "| arm | " + " | ".join(h for _, h in COLUMNS) + " | best step |", "|---|" + "---|" * (len(COLUMNS) + 1)]
    for style_input, label in ARMS:
        runs = arms[style_input]["runs"]
        cells = [_mean_se([r["metrics"][k] for r in runs]) for k, _ in COLUMNS]
        lines.append(f"| {label} | " + " | ".join(cells) + " | " + ", ".join(str(r["best_step"]) for r in runs) + " |")
    lines.append("| GT (oracle) | " + " | ".join(f"{gt[k]:.3f}" if k in gt else "–" for k, _ in COLUMNS) + " | – |")
    lit, past = (arms[s]["runs"] for s, _ in ARMS)
    lines += ["", "Paired per-seed difference, leak-free − literal (mean ± s.e., seeds where leak-free is lower):", "",
              "| column | Δ | seeds lower |", "|---|---|---|"]
    for key, header in COLUMNS:
        d = np.array([b["metrics"][key] - a["metrics"][key] for a, b in zip(lit, past)])
        lines.append(f"| {header} | {d.mean():+.3f} ± {d.std(ddof=1) / math.sqrt(len(d)):.3f} | "
                     f"{int((d < 0).sum())} of {len(d)} |")
    data["gt_cross_session_ce"] = float(np.mean([session_ce(gt_styles[i], gt_styles[j])
                                                 for i in range(len(clips)) for j in range(len(clips)) if i != j]))
    lines += ["", "Style transfer (reference: speaker B's first train session; CE(X, Y) = 1 − ū_X·ū_Y, ū the mean "
                  "unit evaluator embedding; per test session A the mean over the 7 other speakers B and the seeds; "
                  f"tests over the {len(clips)} sessions; ground-truth sessions of two different speakers: CE "
                  f"{data['gt_cross_session_ce']:.3f}):", "",
              "| arm | own style: CE to A | own: CE to B | transfer: CE to A | transfer: CE to B | "
              "transfer CE to B − to A (Wilcoxon p, t p) | CE to B, transfer − own (Wilcoxon p, t p) | "
              "(to B − to A), transfer − own (Wilcoxon p, t p) |",
              "|---|---|---|---|---|---|---|---|"]
    data["transfer_tests"] = {}
    for style_input, label in ARMS:
        runs = arms[style_input]["runs"]
        per = {k: np.mean([r["transfer"][k] for r in runs], axis=0) for k in runs[0]["transfer"]}
        ab = paired_tests(per["transfer_to_B"], per["transfer_to_A"])
        moved = paired_tests(per["transfer_to_B"], per["own_to_B"])
        relative = paired_tests(per["transfer_to_B"] - per["transfer_to_A"], per["own_to_B"] - per["own_to_A"])
        data["transfer_tests"][style_input] = {"to_B_minus_to_A": ab, "transfer_minus_own_to_B": moved,
                                               "relative_to_B_transfer_minus_own": relative}
        lines.append(f"| {label} | {per['own_to_A'].mean():.3f} | {per['own_to_B'].mean():.3f} | "
                     f"{per['transfer_to_A'].mean():.3f} | {per['transfer_to_B'].mean():.3f} | "
                     f"{_test_cell(ab)} | {_test_cell(moved)} | {_test_cell(relative)} |")
    secs = [r["train_seconds"] for s, _ in ARMS for r in arms[s]["runs"]]
    lines += ["", f"Training windows per arm: {lit[0]['train_windows']} (both arms); training wall time "
                  f"{min(secs):.0f}–{max(secs):.0f} s per generator (1 thread, nice 10, shared 2-core machine)."]
    return "\n".join(lines) + "\n"


def _test_cell(t: dict) -> str:
    return (f"{t['mean']:+.4f} ± {t['se']:.4f}, lower in {t['lower']} of {t['n']} "
            f"(p {t['wilcoxon_p']:.3f}, {t['t_p']:.3f})")


if __name__ == "__main__":
    main()
