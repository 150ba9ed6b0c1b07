"""Score ``dyadbench eval`` runs with the Learning2Listen-line suite on the split they were generated from.

SFMS is a listening-head model, and its paper reports the L2L-line metrics (FD and P-FD per component).
This command re-scores the prediction folders that ``dyadbench eval --out RUN`` wrote (for SFMS and for
the baselines) with :func:`dyadbench.scoring.l2l.score_arrays` — ground truth = the agent's motion,
speaker = the partner's motion — and prints / writes one comparison table::

    python -m models.sfms.l2l_compare runs/sfms runs/mean-frame ... --out benchmarks/results/sfms_l2l.md
"""

from __future__ import annotations

import math
import shlex
import sys
from pathlib import Path

import click
import numpy as np
import torch

from dyadbench import atomic
from dyadbench.arrays import load_npy
from dyadbench.errors import InputError
from dyadbench.protocol.runner import open_dataset_split
from dyadbench.results import EvalResult, load_result
from dyadbench.scoring import l2l
from dyadbench.scoring.report import ScoreItem
from models.sfms.bundle import load_tokenizer
from models.sfms.tokenizer import SFMSTokenizer

HEADERS = {"fd_exp": "FD exp", "fd_pose": "FD rot", "pfd_exp": "P-FD exp", "pfd_pose": "P-FD rot"}
COLUMNS = tuple(HEADERS)


def run_items(result: EvalResult, run: Path, clips: int | None = None, data: Path | None = None
              ) -> list[ScoreItem]:
    """ScoreItems of one eval run: prediction, the agent's ground truth and the partner's motion.

    ``clips``: only the predictions of the first N clips (sorted ids), to compare runs on a common subset.
    ``data``: the dataset root the run was evaluated on (None: the embedded corpus / the adapter's default).
    """
    pred_dir = Path(result.predictions) if result.predictions else run / "predictions"
    files = sorted(pred_dir.glob("*.npy"))
    if clips is not None:
        keep = sorted({f.stem.rpartition("_")[0] for f in files})[:clips]
        files = [f for f in files if f.stem.rpartition("_")[0] in keep]
    if not files:
        raise InputError(pred_dir, "no predictions (run `dyadbench eval ... --out RUN` to keep them)")
    source = open_dataset_split(result.data.dataset, data, result.data.split)
    clips, items = {}, []
    for path in files:
        clip_id, _, agent = path.stem.rpartition("_")
        clip = clips.get(clip_id) or clips.setdefault(clip_id, source.load(clip_id))
        partner = clip.partner_of(agent)
        if partner is None:
            raise InputError(path, "the L2L suite needs two-participant clips")
        pred = load_npy(path)
        n = min(len(pred), clip.num_frames)
        items.append(ScoreItem(path.stem, pred[:n], clip.participant(agent).motion[:n], partner.motion[:n],
                               fps=clip.fps))
    return items


@torch.no_grad()
def reconstruction_items(tokenizer: SFMSTokenizer, items: list[ScoreItem]) -> list[ScoreItem]:
    """The same items with ``pred`` = the tokenizer's reconstruction of the ground truth (whole 48-frame
    windows): what SFMS would output if its predictor recovered the ground-truth classes exactly."""
    w, out = tokenizer.cfg.window, []
    for item in items:
        n = (len(item.gt) // w) * w
        gt = torch.as_tensor(np.asarray(item.gt[:n], np.float32))
        windows = tokenizer.normalise(gt.reshape(-1, w, gt.shape[1]))
        rec = tokenizer.denormalise(tokenizer.reconstruct(windows)).reshape(n, -1).numpy()
        out.append(ScoreItem(item.stem, rec, item.gt[:n], item.partner[:n], fps=item.fps))
    return out


def table(rows: list[dict]) -> str:
    head = "| model | context n | predictions | " + " | ".join(HEADERS.values()) + " |"
    lines = [head, "|" + "---|" * (3 + len(COLUMNS))]
    for r in sorted(rows, key=lambda r: r["fd_exp"]):
        values = " | ".join(f"{r[c]:.4f}" if math.isfinite(r[c]) else "–" for c in COLUMNS)
        lines.append(f"| {r['model']} | {r['context']} | {r['items']} | {values} |")
    return "\n".join(lines)


@click.command()
@click.argument("runs", nargs=-1, required=True, type=click.Path(exists=True, file_okay=False, path_type=Path))
@click.option("--seed", default=0, show_default=True, help="Seed of the suite's randomised parts (k-means).")
@click.option("--data", type=click.Path(exists=True, file_okay=False, path_type=Path), default=None,
              help="Dataset root the runs were evaluated on (default: the embedded synthetic corpus).")
@click.option("--clips", type=click.IntRange(min=1), default=None,
              help="Score only the first N clips (sorted ids) of every run: a common subset.")
@click.option("--tokenizer-bound", type=click.Path(exists=True, dir_okay=False, path_type=Path), default=None,
              help="SFMS checkpoint: add a row scoring its tokenizer's reconstruction of the ground truth "
                   "(a perfect-predictor reference), on the first run's items.")
@click.option("--out", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="Markdown file to write the table to (atomically).")
def main(runs: tuple[Path, ...], seed: int, data: Path | None, clips: int | None, tokenizer_bound: Path | None,
         out: Path | None) -> None:
    """Re-score RUNS (folders written by `dyadbench eval --out`) with the L2L-line suite."""
    rows = []

    def add(name: str, context: object, items: list[ScoreItem]) -> None:
        report = l2l.score_arrays(items, seed=seed)
        rows.append({"model": name, "context": context, "items": report.n_scored,
                     **{c: float(report.metrics.get(c, np.nan)) for c in COLUMNS}})
        click.echo(f"{name}: " + ", ".join(f"{c} {rows[-1][c]:.4f}" for c in COLUMNS), err=True)

    first_items = None
    for run in runs:
        result = load_result(run / "result.json")
        items = run_items(result, run, clips, data)
        first_items = first_items or items
        add(result.model.name, result.protocol.context, items)
    if tokenizer_bound is not None:
        add("sfms tokenizer reconstruction of the ground truth (perfect-predictor reference)", "–",
            reconstruction_items(load_tokenizer(tokenizer_bound), first_items))
    text = table(rows)
    click.echo(text)
    if out is not None:
        command = "python -m models.sfms.l2l_compare " + " ".join(shlex.quote(a) for a in sys.argv[1:])
        atomic.write_text(out, f"L2L-line suite (seed {seed}), scored by `{command}`\n\n{text}\n")


if __name__ == "__main__":
    main()
