"""Trainers: ``dyadbench train stygazetalk-style`` (stage 1) and ``dyadbench train stygazetalk`` (stage 2)."""

from __future__ import annotations

import functools
from dataclasses import replace
from pathlib import Path
from typing import Callable

import click

from dyadbench.cli.options import SEED, deprecated_alias, real, required, torch_device
from dyadbench.errors import ConfigError
from dyadbench.outputs import check_cache, check_file
from models.stygazetalk.config import CHECKPOINT_SELECTIONS, STYLE_INPUTS

DEVICE_HELP = ("Torch device to train on: cpu, cuda or cuda:N (batches are drawn on the CPU, seeded alike on every "
               "device; a GPU's arithmetic differs from the CPU's in the last bits, so the weights do too). The "
               "device and the command are recorded in the checkpoint.")
DEVICE_OPTION = click.option("--device", default="cpu", show_default=True, callback=torch_device, help=DEVICE_HELP)
THREADS_HELP = "Torch CPU threads (the committed tiny checkpoints were trained with 1; results can differ in the last bits with more)."
DATASET_HELP = "Registered gaze-head dataset (see `dyadbench datasets`): synthetic-gaze (embedded) or gaze."


def data_options(val_help: str) -> Callable:
    """--dataset / --data / --train-split / --val-split, shared by both trainers."""
    options = [
        click.option("--dataset", default="synthetic-gaze", show_default=True, help=DATASET_HELP),
        click.option("--data", "root", type=click.Path(file_okay=False, path_type=Path), default=None,
                     help="Dataset root folder (default: the embedded synthetic sessions, generated on first use)."),
        click.option("--train-split", default="train", show_default=True, help="Split to train on."),
        click.option("--val-split", default="val", show_default=True, help=val_help),
    ]
    return lambda f: functools.reduce(lambda g, opt: opt(g), reversed(options), f)


def _open(dataset: str, root: Path | None, split: str):
    from dyadbench.registry import DATASETS
    return DATASETS.load(dataset)(root, split)


def _overrides(base, **values):
    given = {k: v for k, v in values.items() if v is not None}
    return replace(base, **given) if given else base


@click.command("stygazetalk-style")
@click.option("--config", "config_name", default="tiny-se64", show_default=True,
              help="Style-encoder preset: tiny-se64, tiny-se32, base-se64, base-se32.")
@data_options("Split for early-stopping selection (validation NT-Xent) and the retrieval check.")
@click.option("--steps", type=click.IntRange(min=1), default=None, help="Override the preset's step count.")
@click.option("--batch-size", "batch", type=click.IntRange(min=2), default=None,
              help="Override the preset's pairs per batch (anchors of one session stay >= 10 s apart).")
@deprecated_alias("--batch", "--batch-size", "batch", type=click.IntRange(min=2))
@click.option("--seed", type=SEED, default=None, help="Override the preset's seed (recorded in the checkpoint).")
@click.option("--val-every", type=click.IntRange(min=1), default=50, show_default=True,
              help="Evaluate the validation NT-Xent every this many steps.")
@click.option("--threads", type=click.IntRange(min=1), default=1, show_default=True, help=THREADS_HELP)
@DEVICE_OPTION
@click.option("--export", type=click.Path(dir_okay=False, path_type=Path), default=None, callback=required,
              help="Checkpoint file to write (atomically; the weights to ship or pass to `dyadbench eval "
                   "--weights`). Required.")
@deprecated_alias("--out", "--export", "export", type=click.Path(dir_okay=False, path_type=Path))
def train_style_encoder(config_name: str, dataset: str, root: Path | None, train_split: str, val_split: str,
                        steps: int | None, batch: int | None, seed: int | None, val_every: int, threads: int,
                        device: str, export: Path) -> None:
    """Stage 1: train the contrastive (NT-Xent) style encoder on adjacent windows of one speaker.

    Prints the validation NT-Xent curve and the top-1 same-speaker retrieval accuracy of the selected
    weights on the validation windows (against its chance level).
    """
    import torch

    from dyadbench.training.checkpoint import run_record
    from models.stygazetalk.checkpoints import save_style_model
    from models.stygazetalk.config import get_style_config
    from models.stygazetalk.data import load_segments
    from models.stygazetalk.train_style import (cross_session_retrieval, retrieval_accuracy, tiled_windows,
                                                train_style_encoder as fit)

    check_cache()
    check_file(export, f"--export {export}")
    torch.set_num_threads(threads)
    cfg = _overrides(get_style_config(config_name), steps=steps, batch_pairs=batch, seed=seed)
    min_frames = 2 * cfg.window + cfg.pair_gap_max
    train_src, val_src = _open(dataset, root, train_split), _open(dataset, root, val_split)
    train = load_segments(train_src, cfg.angle_limit_deg, min_frames)
    val = load_segments(val_src, cfg.angle_limit_deg, min_frames)
    model, log = fit(cfg, train, val, val_every=val_every, device=device)
    windows, speakers, _ = tiled_windows(val, cfg.window)
    acc, chance = retrieval_accuracy(model.embed_degrees(windows), speakers)
    meta = {"data": {"train": train_src.describe(), "val": val_src.describe()}, "seed": cfg.seed,
            "steps": cfg.steps, "best_step": log.best_step, "best_val_nt_xent": log.best_val,
            "train_seconds": log.seconds, **run_record(device, threads),
            "val_retrieval_top1": acc, "val_retrieval_chance": chance,
            "curve": log.curve()}
    path = save_style_model(export, model, meta)
    cross, cross_chance = cross_session_retrieval(model, val, train)
    click.echo(f"style encoder {cfg.name}: best val NT-Xent {log.best_val:.4f} at step {log.best_step} "
               f"({log.seconds:.0f} s); val retrieval top-1 {acc:.3f} (chance {chance:.3f}); cross-session "
               f"val -> train top-1 {cross:.3f} (chance {cross_chance:.3f}); wrote {path}")


@click.command("stygazetalk")
@click.option("--config", "config_name", default="tiny-se64", show_default=True,
              help="Generator preset <size>-<variant>: size tiny|base; variant base, se32, se64, se64-vel, "
                   "tfm-se64, mpgw-sim (mpgw-sim differs only at inference: corrupted seed).")
@click.option("--style-encoder", "style_path", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="Stage-1 checkpoint (required for every variant but base); it is frozen and copied "
                   "into the generator checkpoint together with its motion statistics.")
@data_options("Split for checkpoint selection (teacher-forced validation loss).")
@click.option("--steps", type=click.IntRange(min=1), default=None, help="Override the preset's step count.")
@click.option("--batch-size", "batch", type=click.IntRange(min=1), default=None,
              help="Override the preset's batch size.")
@deprecated_alias("--batch", "--batch-size", "batch", type=click.IntRange(min=1))
@click.option("--lam", type=real(0, 1), default=None,
              help="Override lambda in lambda*MSE + (1-lambda)*velocity MSE (D21).")
@click.option("--rollout-prob", type=real(0, 1), default=None,
              help="Override the share of training steps whose last N-1 inputs are the model's own outputs "
                   "(scheduled sampling, D9; 0 = teacher forcing only).")
@click.option("--seed", type=SEED, default=None, help="Override the preset's seed (recorded in the checkpoint).")
@click.option("--selection", type=click.Choice(list(CHECKPOINT_SELECTIONS)), default=None,
              help="Override which weights are kept: lowest validation L_gen (preset, D27), lowest validation "
                   "MSE alone (val-mse: one criterion whatever --lam), or the final step.")
@click.option("--style-input", type=click.Choice(list(STYLE_INPUTS)), default=None,
              help="Override the training style window (D7): motion-window = the motion inputs (the paper's "
                   "literal reading, covers the targets), past = the M frames before the first scored target "
                   "(leak-free, as at inference), preceding = the M frames before the motion inputs.")
@click.option("--threads", type=click.IntRange(min=1), default=1, show_default=True, help=THREADS_HELP)
@DEVICE_OPTION
@click.option("--export", type=click.Path(dir_okay=False, path_type=Path), default=None, callback=required,
              help="Checkpoint file to write (atomically; the weights to ship or pass to `dyadbench eval "
                   "--weights`). Required.")
@deprecated_alias("--out", "--export", "export", type=click.Path(dir_okay=False, path_type=Path))
def train_generator(config_name: str, style_path: Path | None, dataset: str, root: Path | None, train_split: str,
                    val_split: str, steps: int | None, batch: int | None, lam: float | None,
                    rollout_prob: float | None, seed: int | None, selection: str | None, style_input: str | None,
                    threads: int, device: str, export: Path) -> None:
    """Stage 2: train the motion generator (teacher forcing, style encoder frozen).

    The kept weights are those with the lowest teacher-forced validation loss (the preset's selection),
    or, with --selection, those with the lowest validation MSE alone or the final ones.
    """
    import torch

    from dyadbench.training.checkpoint import file_digest, run_record
    from models.stygazetalk.checkpoints import load_style_model, save_system, system_from_style
    from models.stygazetalk.config import get_generator_config
    from models.stygazetalk.data import load_segments
    from models.stygazetalk.train_generator import style_history, train_generator as fit

    check_cache()
    check_file(export, f"--export {export}")
    torch.set_num_threads(threads)
    cfg = _overrides(get_generator_config(config_name), steps=steps, batch=batch, lam=lam,
                     rollout_prob=rollout_prob, seed=seed, checkpoint_selection=selection,
                     style_input=style_input).validate()
    style, style_digest = None, None
    if cfg.style:
        if style_path is None:
            raise ConfigError(f"{cfg.name} conditions on a style encoder: pass --style-encoder "
                              f"(train one with `dyadbench train stygazetalk-style --config tiny-se{cfg.d_s}`)")
        style, _ = load_style_model(style_path)
        style_digest = file_digest(style_path)
    system = system_from_style(cfg, style)
    pre = style_history(cfg)
    train_src, val_src = _open(dataset, root, train_split), _open(dataset, root, val_split)
    train = load_segments(train_src, cfg.angle_limit_deg, cfg.window + 1 + pre)
    val = load_segments(val_src, cfg.angle_limit_deg, cfg.window + 1 + pre)
    log = fit(system, train, val, device=device)
    meta = {"data": {"train": train_src.describe(), "val": val_src.describe()}, "seed": cfg.seed,
            "steps": cfg.steps, "style_encoder_digest": style_digest, "best_step": log.best_step,
            "best_val_loss": log.best_val, "step0_val_loss": log.step0_val_loss, "train_seconds": log.seconds,
            **run_record(device, threads),
            "train_windows": log.train_windows,
            "curve": log.curve()}
    path = save_system(export, system, meta)
    kept = f"best step {log.best_step}" if cfg.checkpoint_selection != "last" else \
        f"final weights kept; best step was {log.best_step}"
    tracked = "MSE" if cfg.checkpoint_selection == "val-mse" else "loss"
    click.echo(f"generator {cfg.name} ({cfg.variant}): val {tracked} {log.step0_val_loss:.4f} -> {log.best_val:.4f} "
               f"({kept}, {log.seconds:.0f} s); wrote {path}")
