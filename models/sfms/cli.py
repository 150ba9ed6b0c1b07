"""``dyadbench train sfms-tokenizer`` and ``dyadbench train sfms``: the two SFMS training stages.

Single process by default; under ``torchrun --nproc_per_node N -m dyadbench train ...`` the same
commands train data-parallel (torch.distributed; rank 0 validates and writes the checkpoint).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Iterable

import click
import torch
from tqdm import tqdm

from dyadbench import atomic
from dyadbench.cli.options import COUNT, SEED, deprecated_alias, real, required, torch_device
from dyadbench.datasets.base import ClipSource, DyadicClip
from dyadbench.errors import ConfigError
from dyadbench.registry import DEFAULT_EMBEDDED
from dyadbench.outputs import check_cache, check_file
from dyadbench.registry import DATASETS
from dyadbench.seeding import rng as seeded_rng
from dyadbench.training.checkpoint import file_digest, run_record, save_checkpoint
from models.sfms.bundle import PREDICTOR_MODEL, TOKENIZER_MODEL, load_tokenizer
from models.sfms.config import PREDICTOR_PRESETS, TOKENIZER_PRESETS, predictor_preset, to_dict, tokenizer_preset
from models.sfms.data import clip_motions, directed_clips, motion_stats, normalise_directed, row_stats
from models.sfms.distributed import close_world, init_world
from models.sfms.train_predictor import fit_predictor
from models.sfms.train_tokenizer import eval_windows, fit_tokenizer


def parse_overrides(pairs: tuple[str, ...]) -> dict:
    """``FIELD=VALUE`` pairs; VALUE is read as JSON (numbers, booleans, lists, null) or else a string."""
    out = {}
    for pair in pairs:
        key, sep, value = pair.partition("=")
        if not sep:
            raise ConfigError(f"--set expects FIELD=VALUE, got {pair!r}")
        try:
            out[key] = json.loads(value)
        except json.JSONDecodeError:
            out[key] = value
        if isinstance(out[key], list):
            out[key] = tuple(out[key])
    return out


def load_split_clips(dataset: str, root: Path | None, clips: int | None, val_frac: float,
                     seed: int) -> tuple[Iterable[DyadicClip], Iterable[DyadicClip], dict]:
    """The train split (first ``clips`` clips), divided into train / validation clips by a seeded draw.

    The clips are returned as lazy iterables (read one at a time), so a large split never sits in memory.
    """
    source = DATASETS.load(dataset)(root, "train")
    ids = source.clip_ids()[:clips] if clips else source.clip_ids()
    if len(ids) < 2:
        raise ConfigError(f"need at least 2 training clips, {dataset}/train has {len(ids)}")
    order = seeded_rng(seed, "sfms-val").permutation(len(ids))
    n_val = max(1, int(round(val_frac * len(ids))))
    if n_val >= len(ids):
        raise ConfigError(f"--val-frac {val_frac} holds out all {len(ids)} clips; none is left to train on")
    val_ids = sorted(ids[i] for i in order[:n_val])
    train_ids = [i for i in ids if i not in set(val_ids)]
    describe = {**source.describe(), "layout": source.load(ids[0]).layout, "clips_used": len(ids),
                "val_clips": val_ids}
    return _lazy(source, train_ids), _lazy(source, val_ids), describe


def _lazy(source: ClipSource, ids: list[str]) -> Iterable[DyadicClip]:
    return (source.load(i) for i in tqdm(ids, desc=f"read {source.dataset}/{source.split}", unit="clip",
                                         leave=False))


def _common(f):
    options = [
        click.option("--config", "preset", default="tiny", show_default=True,
                     help="Preset: tiny (minutes on 2 CPU cores) or paper (window 48, width 256)."),
        click.option("--set", "overrides", multiple=True, metavar="FIELD=VALUE",
                     help="Override any config field (every spec decision is one), e.g. --set keyframes=10."),
        click.option("--dataset", default=DEFAULT_EMBEDDED, show_default=True,
                     help="Registered dataset to train on (`dyadbench datasets`)."),
        click.option("--data", "root", type=click.Path(path_type=Path), default=None,
                     help="Dataset root (default: the dataset's own default, e.g. the embedded corpus cache)."),
        deprecated_alias("--root", "--data", "root", type=click.Path(path_type=Path)),
        click.option("--clips", type=click.IntRange(min=2), default=None,
                     help="Use only the first N train clips (quick runs; at least 2: one is held out)."),
        click.option("--val-frac", type=real(0, 1, min_open=True, max_open=True), default=0.1, show_default=True,
                     help="Fraction of train clips held out for validation / best-checkpoint selection."),
        click.option("--val-windows", type=COUNT, default=512, show_default=True,
                     help="Validation windows scored at each validation (best-checkpoint selection)."),
        click.option("--steps", type=COUNT, default=None, help="Training steps (default: the preset's)."),
        click.option("--batch-size", "batch", type=COUNT, default=None,
                     help="Windows per step (default: the preset's)."),
        deprecated_alias("--batch", "--batch-size", "batch", type=COUNT),
        click.option("--seed", type=SEED, default=0, show_default=True, help="Seed of every random choice."),
        click.option("--threads", type=COUNT, default=1, show_default=True,
                     help="torch CPU threads (1 is fastest on a shared, busy CPU)."),
        click.option("--device", default="cpu", show_default=True, callback=torch_device,
                     help="cpu, cuda or cuda:N (one GPU per process); a device this machine lacks is refused."),
        click.option("--export", type=click.Path(dir_okay=False, path_type=Path), default=None, callback=required,
                     help="Checkpoint file to write (the weights to ship or pass to `dyadbench eval --weights`; "
                          "its training history goes beside it as <name>.history.json). Required."),
        deprecated_alias("--out", "--export", "export", type=click.Path(dir_okay=False, path_type=Path)),
    ]
    for option in reversed(options):
        f = option(f)
    return f


def _overrides(overrides: tuple[str, ...], steps: int | None, batch: int | None) -> dict:
    out = parse_overrides(overrides)
    out.update({k: v for k, v in (("steps", steps), ("batch", batch)) if v is not None})
    return out


def _write_log(export: Path, history: dict) -> Path:
    return atomic.write_json(export.with_suffix(".history.json"), history)


@click.command("sfms-tokenizer")
@_common
@click.option("--keyframes", type=COUNT, default=None, help="k keyframes per 48-frame window (D11).")
@click.option("--keyframe-mode", type=click.Choice(["dynamic", "static", "dense"]), default=None,
              help="dynamic = learned Gumbel top-k; static = uniform i·⌊T/k⌋; dense = every frame.")
@click.option("--quantizer", type=click.Choice(["fsq", "vq"]), default=None, help="Keyframe quantiser.")
@click.option("--mask-sharing", type=click.Choice(["frame", "channel"]), default=None,
              help="Keyframe allocation (D1; same as --set mask_sharing=...): frame = one mask of k keyframes "
                   "shared by all channels (the preset's, and the shipped checkpoints'); channel = every channel "
                   "picks its own k keyframes (the paper's per-channel allocation; classes per frame and channel).")
def train_tokenizer(preset, overrides, dataset, root, clips, val_frac, val_windows, steps, batch, seed, threads,
                    device, export, keyframes, keyframe_mode, quantizer, mask_sharing) -> None:
    """SFMS stage 1: train the sparse keyframe tokenizer (scorer + FSQ/VQ + inpainter).

    \b
    Example (the shipped tiny tokenizer of the default corpus v2; --dataset synthetic for v1's):
      dyadbench train sfms-tokenizer --config tiny --export sfms-tok.pt
    """
    check_cache()
    check_file(export, f"--export {export}")
    torch.set_num_threads(threads)
    extra = _overrides(overrides, steps, batch)
    extra.update({k: v for k, v in (("keyframes", keyframes), ("keyframe_mode", keyframe_mode),
                                    ("quantizer", quantizer), ("mask_sharing", mask_sharing)) if v is not None})
    if preset not in TOKENIZER_PRESETS:
        raise ConfigError(f"unknown config {preset!r} (known: {', '.join(TOKENIZER_PRESETS)})")
    cfg = tokenizer_preset(preset, **extra)
    world = init_world(device)
    try:
        train, val, describe = load_split_clips(dataset, root, clips, val_frac, seed)
        train_motion = clip_motions(train)
        mean, std = motion_stats(train_motion, cfg.normalisation)
        norm = [(a - mean) / std for a in train_motion]
        val_set = eval_windows([(a - mean) / std for a in clip_motions(val)], cfg.window, limit=val_windows)
        model, history = fit_tokenizer(cfg, norm, val_set, motion_mean=mean, motion_std=std,
                                       seed=seed + world.rank, world=world)
        if world.main:
            meta = {"model": TOKENIZER_MODEL, "preset": preset, "seed": seed, "data": describe,
                    "best_val_mse_z": history["best_val_mse_z"], "best_step": history["best_step"],
                    "train_seconds": history["train_seconds"], "world_size": world.size, "val": history["val"],
                    **run_record(device, threads)}
            save_checkpoint(export, model_state=model.state_dict(), config={"tokenizer": to_dict(cfg)}, meta=meta)
            log = _write_log(export, history)
            click.echo(f"tokenizer: best validation MSE {history['best_val_mse_z']:.4f} (z-space) at step "
                       f"{history['best_step']}, {history['train_seconds']:.0f} s -> {export} (history {log})")
    finally:
        close_world(world)


@click.command("sfms")
@_common
@click.option("--tokenizer", "tokenizer_path", type=click.Path(path_type=Path, exists=True, dir_okay=False),
              required=True, help="Stage-1 checkpoint from `dyadbench train sfms-tokenizer`.")
def train_predictor(preset, overrides, dataset, root, clips, val_frac, val_windows, steps, batch, seed, threads,
                    device, export, tokenizer_path) -> None:
    """SFMS stage 2: train the listening-head predictor on top of a frozen tokenizer.

    The keyframe allocation is the tokenizer's (its mask_sharing, set with `train sfms-tokenizer
    --mask-sharing`): a per-channel tokenizer gives a predictor of classes per frame and channel.

    \b
    Example (the shipped tiny model of the default corpus v2; one command line; for corpus v1 both stages
    take --dataset synthetic and it exports models/sfms/checkpoints/sfms-tiny.pt):
      dyadbench train sfms --config tiny --clips 400 --steps 4000 --tokenizer sfms-tok.pt
          --export models/sfms/checkpoints/sfms-tiny-v2.pt

    \b
    The REACT variant (25-d emotion features, no audio branch; models/sfms/react.py), on the embedded
    corpus written in the REACT layout into out/react-synth (dyadbench data synth --layout react --split train):
      dyadbench train sfms-tokenizer --config tiny --dataset react --data out/react-synth --set dim=25
          --export out/sfms-tok-react.pt
      dyadbench train sfms --config tiny --dataset react --data out/react-synth --steps 8000
          --set speaker_audio=none --set audio_bins=1 --tokenizer out/sfms-tok-react.pt
          --export models/sfms/checkpoints/sfms-tiny-react.pt
    """
    check_cache()
    check_file(export, f"--export {export}")
    torch.set_num_threads(threads)
    if preset not in PREDICTOR_PRESETS:
        raise ConfigError(f"unknown config {preset!r} (known: {', '.join(PREDICTOR_PRESETS)})")
    cfg = predictor_preset(preset, **_overrides(overrides, steps, batch))
    tokenizer = load_tokenizer(tokenizer_path)
    world = init_world(device)
    try:
        train, val, describe = load_split_clips(dataset, root, clips, val_frac, seed)
        raw_train, raw_val = directed_clips(train, cfg), directed_clips(val, cfg)
        audio_mean, audio_std = row_stats(raw_train)
        mm, ms = tokenizer.motion_mean.numpy(), tokenizer.motion_std.numpy()
        train_set = normalise_directed(raw_train, mm, ms, audio_mean, audio_std)
        val_set = normalise_directed(raw_val, mm, ms, audio_mean, audio_std)
        del raw_train, raw_val
        model, history = fit_predictor(cfg, tokenizer, train_set, val_set, audio_mean=audio_mean,
                                       audio_std=audio_std, seed=seed + world.rank, world=world,
                                       val_windows=val_windows)
        if world.main:
            meta = {"model": PREDICTOR_MODEL, "preset": preset, "seed": seed, "data": describe,
                    "tokenizer": str(tokenizer_path), "tokenizer_sha256": file_digest(tokenizer_path),
                    "best_val_ce": history["best_val_ce"],
                    "best_step": history["best_step"], "train_seconds": history["train_seconds"],
                    "world_size": world.size, "val": history["val"], **run_record(device, threads)}
            save_checkpoint(export, model_state=model.state_dict(), config=model.config(), meta=meta)
            log = _write_log(export, history)
            last = history["val"][-1]
            click.echo(f"predictor: best validation weighted CE {history['best_val_ce']:.3f} (unigram "
                       f"{last['unigram_ce']:.3f}), {history['train_seconds']:.0f} s -> {export} (history {log})")
    finally:
        close_world(world)
