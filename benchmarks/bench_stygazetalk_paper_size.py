"""StyGazeTalk at the paper's size against the shipped tiny checkpoint (issue #26's paper-size run).

The paper-size pair is trained with the user's trainers and the ``base`` presets (the spec's sizes: style
encoder 4 layers, generator LSTM 3 × 256, 20,000 and 30,000 steps, batch 32 pairs and 64 windows); the
committed pair in ``models/stygazetalk/weights/`` was made with

    dyadbench train stygazetalk-style --config base-se64 --export runs/paper/style-encoder-base-se64.pt
    dyadbench train stygazetalk --config base-se64-vel-x1 --style-encoder runs/paper/style-encoder-base-se64.pt \\
        --threads 2 --export runs/paper/stygazetalk-base-se64-vel-x1.pt

(`--device cuda` trains either on a GPU; each file records its command, device and training time.) This
benchmark reads both checkpoints' records (steps, selected step, training time, device, validation loss),
refuses a generator whose recorded style encoder is not the file given, streams both generators over the
test and ood sessions of the embedded gaze corpus through the protocol (n = ``--context``), scores them with
the gaze–head suite and the shipped style evaluator, once with each checkpoint's own decoding (X1: sampled
eye angles, protocol seed 0) and once with mean decoding (deterministic), and reports the style encoders'
speaker retrieval. The naive static baseline and GT run in the same pass as references.

    python benchmarks/bench_stygazetalk_paper_size.py      # the committed pair; --paper/--paper-style for others
Writes benchmarks/results/stygazetalk_paper_size.{json,md}.
"""

from __future__ import annotations

import sys
from pathlib import Path

import click

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_stygazetalk_variants import COLUMNS, _arrays, _fmt, _retrieval, stream_items  # noqa: E402
from output import write_result  # noqa: E402  (benchmarks/output.py)
from dyadbench.protocol.config import ProtocolConfig  # noqa: E402
from dyadbench.protocol.interface import ModelOptions  # noqa: E402
from dyadbench.registry import DATASETS  # noqa: E402
from dyadbench.scoring.gaze import score_arrays  # noqa: E402
from dyadbench.training.checkpoint import file_digest  # noqa: E402
from models.stygazetalk.checkpoints import (PAPER_SIZE_MODEL, PAPER_SIZE_STYLE_ENCODER, SHIPPED_MODEL,  # noqa: E402
                                            SHIPPED_STYLE_ENCODER, load_style_model, load_system)
from models.stygazetalk.data import load_segments  # noqa: E402
from models.stygazetalk.evaluator import load_style_evaluator  # noqa: E402

DATASET = "synthetic-gaze"
RESULT = Path(__file__).parent / "results" / "stygazetalk_paper_size.md"
HEADER = ("| split | row | decoding | All MAE↓ | All Vel↓ | All MEE↓ | CE↓ | All BAS↑ | All ΔBAS↑ | Head BAS↑ | "
          "Head ΔBAS↑ | fixation % | CompScore | SimScore↑ | Sim_seq↑ |")


def record(path: Path, style: bool) -> dict:
    """What a checkpoint says about its training (``meta``), its parameter count and its file digest."""
    model, meta = load_style_model(path) if style else load_system(path)
    trained = model if style else model.generator
    settings = meta.get("settings") or {}
    return {"path": str(path), "sha256": file_digest(path), "preset": model.cfg.name,
            "params": sum(p.numel() for p in trained.parameters()), "steps": meta.get("steps"),
            "best_step": meta.get("best_step"), "train_seconds": meta.get("train_seconds"),
            "device": settings.get("device", "not recorded"), "threads": settings.get("threads", "not recorded"),
            "best_val": meta.get("best_val_nt_xent" if style else "best_val_loss"),
            "train_windows": meta.get("train_windows"), "command": meta.get("command", "not recorded"),
            "style_encoder_digest": meta.get("style_encoder_digest")}


def check_pair(generator: dict, style: dict) -> None:
    """Refuse a generator whose recorded stage-1 file (``meta.style_encoder_digest``) is not ``style``."""
    recorded = generator["style_encoder_digest"]
    if recorded != style["sha256"]:
        said = f"sha256 {recorded[:12]}…" if recorded else "no recorded style encoder"
        raise click.UsageError(f"{generator['path']} was trained on a style encoder with {said}, not on "
                               f"{style['path']} (sha256 {style['sha256'][:12]}…); pass the encoder it was "
                               "trained on with --paper-style.")


def metric_row(split: str, label: str, decoding: str, m: dict) -> str:
    vals = [_fmt(m.get(k)) for k in COLUMNS]
    vals[8] = _fmt(100 * m["fix_ratio"])
    return f"| {split} | {label} | {decoding} | " + " | ".join(vals) + " |"


@click.command()
@click.option("--paper", type=click.Path(dir_okay=False, exists=True, path_type=Path), default=PAPER_SIZE_MODEL,
              show_default=True, help="Paper-size generator checkpoint (base-se64-vel-x1).")
@click.option("--paper-style", type=click.Path(dir_okay=False, exists=True, path_type=Path),
              default=PAPER_SIZE_STYLE_ENCODER, show_default=True,
              help="Paper-size style-encoder checkpoint it was trained on (base-se64).")
@click.option("--context", default=7, show_default=True, help="Protocol context n (history turns).")
@click.option("--splits", default="test,ood", show_default=True, help="Gaze corpus splits to stream.")
@click.option("--out", type=click.Path(dir_okay=False, path_type=Path), default=RESULT, show_default=True)
def main(paper: Path, paper_style: Path, context: int, splits: str, out: Path) -> None:
    """Score the paper-size StyGazeTalk against the shipped tiny one; print and write the table."""
    evaluator = load_style_evaluator()
    config = ProtocolConfig(context=context, seed=0)
    generators = {"tiny (shipped)": SHIPPED_MODEL, "paper size": paper}
    encoders = {"tiny (shipped)": SHIPPED_STYLE_ENCODER, "paper size": paper_style}
    records = {label: {"generator": record(path, style=False), "style_encoder": record(encoders[label], style=True)}
               for label, path in generators.items()}
    for stages in records.values():
        check_pair(stages["generator"], stages["style_encoder"])
    rows, data_rows = [], []
    for split in splits.split(","):
        clips = list(DATASETS.load(DATASET)(None, split))

        def add(label: str, decoding: str, items) -> None:
            metrics = score_arrays(items, seed=0, style_encoder=evaluator).metrics
            rows.append(metric_row(split, label, decoding, metrics))
            data_rows.append({"split": split, "row": label, "decoding": decoding, "metrics": metrics})

        add("GT (oracle)", "–", _arrays(clips, [c.participants[0].motion for c in clips]))
        add("gaze-static", "–", stream_items("gaze-static", ModelOptions(), clips, config))
        for label, path in generators.items():
            add(label, "own (X1 sampled eyes)", stream_items("stygazetalk", ModelOptions(weights=path), clips, config))
            add(label, "mean", stream_items("stygazetalk", ModelOptions(weights=path, extra={"decoding": "mean"}),
                                            clips, config))
    test_src, val_src = (DATASETS.load(DATASET)(None, s) for s in ("test", "val"))
    limit = load_style_model(SHIPPED_STYLE_ENCODER)[0].cfg.angle_limit_deg
    test_segs, val_segs = load_segments(test_src, limit, 50), load_segments(val_src, limit, 50)
    retrieval = {label: _retrieval(path, test_segs, val_segs) for label, path in encoders.items()}

    lines = ["# StyGazeTalk: the paper-size presets against the shipped tiny checkpoint", "",
             f"Embedded `{DATASET}` sessions; streaming protocol n = {context}, protocol seed 0; the first 50 frames "
             f"(seed window) are excluded; CE with the shipped evaluator {evaluator.version} (sha256 "
             f"{evaluator.digest[:12]}…). Each checkpoint decodes as configured (X1: eye angles drawn from its "
             "validation residuals at half scale, seeded per stream) and, deterministically, by its mean.", "",
             "## What each checkpoint records of its training", "",
             "| row | stage | preset | parameters | steps (selected) | training time | device | best validation "
             "value | command |", "|---|---|---|---|---|---|---|---|---|"]
    for label, stages in records.items():
        for stage, r in stages.items():
            seconds = "not recorded" if r["train_seconds"] is None else f"{r['train_seconds']:.0f} s"
            value = "–" if r["best_val"] is None else f"{r['best_val']:.4f}"
            command = r["command"] if r["command"] == "not recorded" else f"`{r['command']}`"
            lines.append(f"| {label} | {stage.replace('_', ' ')} | {r['preset']} | {r['params'] / 1e3:.0f} k | "
                         f"{r['steps']} ({r['best_step']}) | {seconds} | {r['device']} | {value} | {command} |")
    lines += ["", "Best validation value: NT-Xent for the style encoders, teacher-forced L_gen for the generators "
                  "(each preset's own selection criterion; the two sizes' values are on the same scale, the "
                  "same validation windows).", "", "## Gaze–head suite", "",
              HEADER, "|---|---|---|" + "---|" * 12, *rows, "",
              "## Style retrieval of the encoders (top-1 same-speaker cosine nearest neighbour, 2-s windows)", "",
              "| encoder | test, leave-one-out | chance | test → val sessions | chance |", "|---|---|---|---|---|"]
    for label, (acc, chance, cross, cross_chance) in retrieval.items():
        lines.append(f"| {label} | {acc:.3f} | {chance:.3f} | {cross:.3f} | {cross_chance:.3f} |")
    text = "\n".join(lines) + "\n"
    click.echo(text)
    write_result(out, text, seed=0, data={"checkpoints": records, "rows": data_rows, "context": context,
                                          "retrieval": {k: dict(zip(("test", "test_chance", "cross", "cross_chance"),
                                                                    v)) for k, v in retrieval.items()}})
    click.echo(f"wrote {out}")


if __name__ == "__main__":
    main()
