"""``dyadbench train timar`` and ``dyadbench train timar-stream``: train TIMAR on a dataset's train split."""

from __future__ import annotations

import functools
from pathlib import Path
from typing import Callable

import click

from dyadbench.cli.eval import TRAIN_DATASET, open_train_split
from dyadbench.cli.invocation import recorded_command
from dyadbench.cli.options import COUNT, NON_NEGATIVE, POSITIVE, SEED, deprecated_alias
from models.timar.config import MOTION_NORMS, PRESETS

OPTIONS = [
    click.option("--config", "config_name", default="tiny", show_default=True, type=click.Choice(list(PRESETS)),
                 help="Model size: tiny (log-mel speech, CPU in minutes), base / large / huge (the paper's "
                      "sizes, wav2vec 2.0 speech; need --wav2vec-weights and a GPU)."),
    click.option("--motion-norm", type=click.Choice(MOTION_NORMS), default=None,
                 help="Motion the model sees and predicts: none (raw, as released) or per_dim (standardised "
                      "with the training mean/std, mapped back at sampling) [default: the config's; tiny: "
                      "per_dim, base/large/huge: none]."),
    click.option("--data", type=click.Path(exists=True, file_okay=False, path_type=Path), default=None,
                 help="Dataset root holding train/ in the DualTalk layout (or that of --dataset, e.g. seamless: "
                      "the model then generates that layout's motion at its frame rate). Default: the embedded "
                      "synthetic corpus (generated into the cache on first use)."),
    TRAIN_DATASET,
    click.option("--clips", type=click.IntRange(min=1), default=None,
                 help="Train on the first N clips of the train split only (quick runs)."),
    click.option("--epochs", type=click.IntRange(min=1), default=1, show_default=True,
                 help="Total epochs (with --resume: the total to reach, counting those already done)."),
    click.option("--batch-size", type=click.IntRange(min=1), default=None,
                 help="Windows per step and process [default: the config's, 32; tiny: 8]."),
    click.option("--lr", type=POSITIVE, default=None, help="Peak learning rate [default: the config's]."),
    click.option("--warmup-epochs", type=NON_NEGATIVE, default=0.0, show_default=True,
                 help="Linear learning-rate warm-up length in epochs (fractions allowed)."),
    click.option("--stride", "stride_turns", type=click.IntRange(min=1), default=8, show_default=True,
                 help="Start of consecutive 8-turn training windows, in turns (8 = non-overlapping)."),
    click.option("--seed", type=SEED, default=0, show_default=True,
                 help="Seed of initialisation, data order, masks and diffusion noise (recorded)."),
    click.option("--run-dir", type=click.Path(file_okay=False, path_type=Path), default=None,
                 help="Run folder for checkpoint.pt (resumable with --resume, rewritten every epoch) "
                      "[default: runs/<model>-<config>]."),
    deprecated_alias("--out", "--run-dir", "run_dir", type=click.Path(file_okay=False, path_type=Path)),
    click.option("--resume", type=click.Path(exists=True, dir_okay=False, path_type=Path), default=None,
                 help="Continue from this checkpoint.pt (same config and data, checked by digest)."),
    click.option("--export", type=click.Path(dir_okay=False, path_type=Path), default=None,
                 help="Weights file: at the end, write the EMA weights alone (no training state) to this "
                      "file, e.g. to ship or pass to `dyadbench eval --weights`."),
    click.option("--device", default="cpu", show_default=True,
                 help="cpu or cuda (under torchrun each process takes cuda:LOCAL_RANK)."),
    click.option("--wav2vec-weights", type=click.Path(exists=True, file_okay=False), default=None,
                 help="Local folder of facebook/wav2vec2-large-960h-lv60-self (wav2vec configs only)."),
]


def _with_options(f: Callable) -> Callable:
    return functools.reduce(lambda g, opt: opt(g), reversed(OPTIONS), f)


def _run(variant: str, config_name: str, motion_norm: str | None, data: Path | None, dataset: str | None,
         clips: int | None, epochs: int, batch_size: int | None, lr: float | None, warmup_epochs: float,
         stride_turns: int, seed: int, run_dir: Path | None, resume: Path | None, export: Path | None,
         device: str, wav2vec_weights: str | None) -> None:
    from dyadbench.outputs import check_cache, check_file, check_folder  # noqa: PLC0415
    from models.timar.config import preset  # noqa: PLC0415
    from models.timar.layouts import configure_for, layout_named  # noqa: PLC0415
    from models.timar.train import MODEL_NAMES, TrainSettings, train_timar_model  # noqa: PLC0415

    run_dir = run_dir or Path("runs") / f"{MODEL_NAMES[variant]}-{config_name}"
    check_cache()
    check_folder(run_dir, f"--run-dir {run_dir}")
    if export is not None:
        check_file(export, f"--export {export}")
    cfg = preset(config_name, variant, **({"motion_norm": motion_norm} if motion_norm else {}))
    source = open_train_split(data, dataset, clips)
    cfg = configure_for(cfg, layout_named(source.load(source.clip_ids()[0]).layout))  # flame56: unchanged
    settings = TrainSettings(epochs=epochs, batch_size=batch_size, lr=lr, warmup_epochs=warmup_epochs, seed=seed,
                             stride_turns=stride_turns, device=device, wav2vec_weights=wav2vec_weights,
                             command=recorded_command() or "")
    path = train_timar_model(cfg, source, run_dir, settings, resume=resume, export=export)
    click.echo(f"checkpoint: {path}")


@click.command("timar")
@_with_options
def train_timar(**kwargs) -> None:
    """Train the faithful TIMAR (window positions, turn-level causal attention).

    \b
    Reproduces the shipped checkpoint of corpus v1 (models/timar/checkpoints/timar-tiny.pt); with
    --dataset synthetic-v2 --export models/timar/checkpoints/timar-tiny-v2.pt, that of corpus v2:
      OMP_NUM_THREADS=1 dyadbench train timar --dataset synthetic --config tiny --stride 4 --epochs 10 \\
          --warmup-epochs 0.05 --seed 0 --export models/timar/checkpoints/timar-tiny.pt
    On the Seamless layout (the model generates its 165 feature columns at 30 fps; see models/timar/layouts.py),
    the shipped models/timar/checkpoints/timar-tiny-seamless.pt, trained on out/seamless-synth (the train split
    that `dyadbench data synth --layout seamless --split train --clips 200` writes there):
      OMP_NUM_THREADS=1 dyadbench train timar --dataset seamless --data out/seamless-synth --config tiny \\
          --stride 4 --epochs 4 --warmup-epochs 0.05 --seed 0 --run-dir runs/timar-tiny-seamless \\
          --export models/timar/checkpoints/timar-tiny-seamless.pt
    Multi-GPU: torchrun --nproc_per_node 8 -m dyadbench train timar --config large --device cuda ...
    """
    _run("faithful", **kwargs)


@click.command("timar-stream")
@_with_options
def train_timar_stream(**kwargs) -> None:
    """Train the streaming-native TIMAR (per-turn sliding band, positions that never shift).

    \b
    Reproduces the shipped checkpoint of corpus v1 (models/timar/checkpoints/timar-stream-tiny.pt):
      OMP_NUM_THREADS=1 dyadbench train timar-stream --dataset synthetic --config tiny --stride 4 --epochs 10 \\
          --warmup-epochs 0.05 --seed 0 --export models/timar/checkpoints/timar-stream-tiny.pt
    """
    _run("stream", **kwargs)


@click.command("convert")
@click.argument("source", type=click.Path(exists=True, dir_okay=False, path_type=Path))
@click.option("--out", "out", required=True, type=click.Path(dir_okay=False, path_type=Path),
              help="Native dyadbench checkpoint to write (atomically), e.g. timar-native.pt.")
@click.option("--heads", type=COUNT, default=None,
              help="Attention heads, which the released file does not store [default: from its model factory: "
                   "timar_base 12, timar_large 16, timar_huge 16; needed for any other factory].")
@click.option("--wav2vec", "wav2vec", type=click.Path(exists=True, file_okay=False, path_type=Path), default=None,
              help="Local wav2vec 2.0 folder the model will run with: checked to give the feature width the "
                   "checkpoint expects (speech_snippet_embed_dim).")
def convert_official(source: Path, out: Path, heads: int | None, wav2vec: Path | None) -> None:
    """Convert the released TIMAR checkpoint SOURCE (main.py's save_model format) into a native file.

    \b
    The file is read with torch.load(weights_only=True), allowing only argparse.Namespace and numpy's
    array globals; its model_ema weights (what the release evaluates with) are mapped onto dyadbench's
    `timar` model, every tensor accounted for. Later runs load OUT without converting and give the same
    predictions as the released file converted in memory:
      dyadbench weights convert TIMAR.pth --wav2vec wav2vec2-large-960h-lv60-self/ --out timar-native.pt
      dyadbench eval --model timar --weights timar-native.pt --wav2vec wav2vec2-large-960h-lv60-self/ \\
          --speech-norm clip --data DualTalk/ --split test --context 7
    The result records the native file's digest and the released file it came from.
    """
    from dyadbench.errors import ConfigError  # noqa: PLC0415  (keeps --help fast)
    from dyadbench.outputs import check_file  # noqa: PLC0415
    from dyadbench.training.checkpoint import save_checkpoint  # noqa: PLC0415
    from models.timar.official import load_official  # noqa: PLC0415

    check_file(out, f"--out {out}")
    model, meta = load_official(source, heads=heads)
    if wav2vec is not None:
        from dyadbench.features.wav2vec import load_wav2vec  # noqa: PLC0415

        width = int(load_wav2vec(wav2vec).config.hidden_size)
        if width != model.cfg.speech_dim:
            raise ConfigError(f"the wav2vec 2.0 model at {wav2vec} gives {width}-d features; {source} expects "
                              f"{model.cfg.speech_dim}-d (speech_snippet_embed_dim)")
    meta = {**meta, "format": "native"}
    meta.pop("dyadbench_version")  # save_checkpoint records the version that writes the file
    path = save_checkpoint(out, model_state=model.state_dict(), config=model.cfg.to_dict(), meta=meta)
    click.echo(f"wrote {path} (timar, {model.cfg.name}: D={model.cfg.dim}, {model.cfg.depth} blocks, "
               f"{model.cfg.heads} heads; model_ema weights of {source})")
