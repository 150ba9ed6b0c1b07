"""Score ``dyadbench eval`` runs with the Learning2Listen-line suite on the split they were generated from.

SFMS is a listening-head model, and its paper reports the L2L-line metrics (FD and P-FD per component).
This command re-scores the prediction folders that ``dyadbench eval --out RUN`` wrote (for SFMS and for
the baselines) with :func:`dyadbench.scoring.l2l.score_arrays` — ground truth = the agent's motion,
speaker = the partner's motion — and prints / writes one comparison table::

    python -m models.sfms.l2l_compare runs/sfms runs/mean-frame ... --out benchmarks/results/sfms_l2l.md

``--frames listening`` scores only the frames where the agent is silent and its partner speaks (the
clip's ``meta["speaking"]`` masks), i.e. the Learning2Listen task: a listener's head while the other person
talks. Whole clips (the default) also hold the agent's own talking, which a listener model is not given.
"""

from __future__ import annotations

import math
import shlex
from pathlib import Path

import click
import numpy as np
import torch

from dyadbench import atomic
from dyadbench.arrays import load_npy
from dyadbench.cli.options import SEED
from dyadbench.datasets.base import DyadicClip
from dyadbench.errors import InputError
from dyadbench.protocol.runner import open_dataset_split
from dyadbench.results import EvalResult, load_result
from dyadbench.scoring import l2l
from dyadbench.scoring.report import ScoreItem
from models.sfms.bundle import load_tokenizer
from models.sfms.tokenizer import SFMSTokenizer

FRAMES = ("all", "listening")
HEADERS = {"fd_exp": "FD exp", "fd_pose": "FD rot", "pfd_exp": "P-FD exp", "pfd_pose": "P-FD rot"}
COLUMNS = tuple(HEADERS)


def listening_frames(clip: DyadicClip, agent: str) -> np.ndarray:
    """(T,) bool: frames where ``agent`` is silent and its partner speaks, from ``clip.meta["speaking"]``."""
    partner = clip.partner_of(agent)
    speaking = clip.meta.get("speaking") or {}
    if partner is None or agent not in speaking or partner.name not in speaking:
        raise InputError(clip.clip_id, "--frames listening needs per-participant speaking masks "
                                       "(meta['speaking']) for both participants; this clip has none")
    masks = [np.asarray(speaking[who], dtype=bool) for who in (agent, partner.name)]
    if any(m.shape != (clip.num_frames,) for m in masks):
        raise InputError(clip.clip_id, f"speaking masks must be ({clip.num_frames},) per participant, got "
                                       f"{[m.shape for m in masks]}")
    return ~masks[0] & masks[1]


def run_items(result: EvalResult, run: Path, clips: int | None = None, data: Path | None = None,
              frames: str = "all") -> tuple[list[ScoreItem], list[np.ndarray]]:
    """ScoreItems of one eval run (prediction, the agent's ground truth, the partner's motion; whole
    sequences) and, per item, the (T,) bool mask of the frames to score (see :func:`restrict`).

    ``clips``: only the predictions of the first N clips (sorted ids), to compare runs on a common subset.
    ``data``: the dataset root the run was evaluated on (None: the embedded corpus / the adapter's default).
    ``frames``: "all", or "listening" (:func:`listening_frames`).
    """
    pred_dir = Path(result.predictions) if result.predictions else run / "predictions"
    files = sorted(pred_dir.glob("*.npy"))
    if clips is not None:
        keep = sorted({f.stem.rpartition("_")[0] for f in files})[:clips]
        files = [f for f in files if f.stem.rpartition("_")[0] in keep]
    if not files:
        raise InputError(pred_dir, "no predictions (run `dyadbench eval ... --out RUN` to keep them)")
    source = open_dataset_split(result.data.dataset, data, result.data.split)
    clips, items, masks = {}, [], []
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
        masks.append(listening_frames(clip, agent)[:n] if frames == "listening" else np.ones(n, dtype=bool))
    return items, masks


def restrict(items: list[ScoreItem], masks: list[np.ndarray], where: object = None) -> list[ScoreItem]:
    """Each item cut to the frames its mask keeps (the mask is cut to the item's length); items with
    fewer than 2 kept frames are left out (the suite needs T ≥ 2). ``where`` names the run in errors."""
    out = []
    for item, mask in zip(items, masks):
        keep = mask[:len(item.pred)]
        if keep.sum() >= 2:
            out.append(ScoreItem(item.stem, item.pred[keep], item.gt[keep], item.partner[keep], fps=item.fps))
    if not out:
        raise InputError(where, "no prediction has 2 or more frames to score under the chosen --frames")
    return out


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


def paired_table(runs: list[tuple[str, list[dict]]]) -> str:
    """The first run against each other one, sequence by sequence (the sequences both scored).

    Per column, d_i = first_i − other_i over the n common sequences; the cell is mean(d) ± s.e. with
    s.e. = std(d, ddof=1)/√n (sequences taken as independent; the two directions of a dialogue share it),
    then how many of the n sequences the first run scores lower. Negative means the first run is better.
    """
    name0, rows0 = runs[0]
    by_clip0 = {r["clip"]: r for r in rows0}
    lines = [f"| {name0} − model | sequences | " + " | ".join(HEADERS.values()) + " |",
             "|" + "---|" * (2 + len(COLUMNS))]
    for name, rows in runs[1:]:
        common = [r for r in rows if r["clip"] in by_clip0]
        if len(common) < 2:
            raise InputError(name, f"shares {len(common)} scored sequences with {name0}; a paired comparison "
                                   "needs 2 or more (compare runs over the same clips)")
        cells = []
        for c in COLUMNS:
            d = np.array([by_clip0[r["clip"]][c] - r[c] for r in common])
            cells.append(f"{d.mean():+.4g} ± {d.std(ddof=1) / math.sqrt(len(d)):.2g} ({int((d < 0).sum())} lower)")
        lines.append(f"| {name} | {len(common)} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


@click.command()
@click.argument("runs", nargs=-1, required=True, type=click.Path(exists=True, file_okay=False, path_type=Path))
@click.option("--seed", default=0, show_default=True, type=SEED, help="Seed of the suite's randomised parts (k-means).")
@click.option("--data", type=click.Path(exists=True, file_okay=False, path_type=Path), default=None,
              help="Dataset root the runs were evaluated on (default: the embedded synthetic corpus).")
@click.option("--clips", type=click.IntRange(min=1), default=None,
              help="Score only the first N clips (sorted ids) of every run: a common subset.")
@click.option("--frames", type=click.Choice(FRAMES), default="all", show_default=True,
              help="Frames scored: every frame, or only those where the agent is silent and its partner "
                   "speaks (the Learning2Listen listener task; needs the clips' speaking masks).")
@click.option("--tokenizer-bound", type=click.Path(exists=True, dir_okay=False, path_type=Path), default=None,
              help="SFMS checkpoint: add a row scoring its tokenizer's reconstruction of the ground truth "
                   "(a perfect-predictor reference), on the first run's items.")
@click.option("--paired", is_flag=True,
              help="Also compare the first run with each other one sequence by sequence: mean ± standard "
                   "error of the per-sequence differences, and how many sequences the first scores lower.")
@click.option("--out", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="Markdown file to write the table(s) to (atomically).")
def main(runs: tuple[Path, ...], seed: int, data: Path | None, clips: int | None, frames: str,
         tokenizer_bound: Path | None, paired: bool, out: Path | None) -> None:
    """Re-score RUNS (folders written by `dyadbench eval --out`) with the L2L-line suite."""
    rows, per_sequence = [], []

    def add(name: str, context: object, items: list[ScoreItem]) -> None:
        report = l2l.score_arrays(items, seed=seed)
        per_sequence.append((name, report.per_item))
        rows.append({"model": name, "context": context, "items": report.n_scored,
                     **{c: float(report.metrics.get(c, np.nan)) for c in COLUMNS}})
        click.echo(f"{name}: " + ", ".join(f"{c} {rows[-1][c]:.4f}" for c in COLUMNS), err=True)

    first = None
    for run in runs:
        result = load_result(run / "result.json")
        items, masks = run_items(result, run, clips, data, frames)
        first = first or (items, masks)
        add(result.model.name, result.protocol.context, restrict(items, masks, run))
    if tokenizer_bound is not None:  # whole windows are reconstructed, then cut like every run
        add("sfms tokenizer reconstruction of the ground truth (perfect-predictor reference)", "–",
            restrict(reconstruction_items(load_tokenizer(tokenizer_bound), first[0]), first[1]))
    text = table(rows)
    if paired:
        text += "\n\n" + paired_table(per_sequence)
    click.echo(text)
    if out is not None:
        given = [*map(str, runs), "--seed", str(seed), "--frames", frames] + (["--paired"] if paired else [])
        for flag, value in (("--data", data), ("--clips", clips), ("--tokenizer-bound", tokenizer_bound)):
            given += [flag, str(value)] if value is not None else []
        command = "python -m models.sfms.l2l_compare " + " ".join(shlex.quote(a) for a in given + ["--out", str(out)])
        atomic.write_text(out, f"L2L-line suite (seed {seed}), scored by `{command}`\n\n{text}\n")


if __name__ == "__main__":
    main()
