"""``dyadbench train dualtalk``: train the log-mel DualTalk on a dataset's train split."""

from __future__ import annotations

from pathlib import Path

import click

from dyadbench.cli.eval import TRAIN_DATASET, open_train_split
from dyadbench.cli.invocation import recorded_command
from dyadbench.cli.options import POSITIVE, SEED, deprecated_alias


@click.command("dualtalk")
@click.option("--data", type=click.Path(exists=True, file_okay=False, path_type=Path), default=None,
              help="Dataset root holding train/ in the DualTalk layout. Default: the embedded synthetic corpus.")
@TRAIN_DATASET
@click.option("--clips", type=click.IntRange(min=1), default=None, help="Train on the first N train clips only.")
@click.option("--steps", type=click.IntRange(min=1), default=1000, show_default=True, help="Optimiser steps.")
@click.option("--batch-size", type=click.IntRange(min=1), default=16, show_default=True, help="Windows per step.")
@click.option("--lr", type=POSITIVE, default=1e-4, show_default=True, help="Adam learning rate (released: 1e-4).")
@click.option("--min-seconds", type=click.IntRange(min=1), default=1, show_default=True,
              help="Shortest training window (whole seconds; the streaming protocol's window at n = 0).")
@click.option("--max-seconds", type=click.IntRange(min=1), default=8, show_default=True,
              help="Longest training window (whole seconds; n = 7 gives 8-s windows).")
@click.option("--feature-dim", type=click.IntRange(min=2), default=None, help="F [default: tiny's, 64].")
@click.option("--seed", type=SEED, default=0, show_default=True, help="Seed of initialisation, windows, dropout.")
@click.option("--save-every", type=click.IntRange(min=1), default=500, show_default=True,
              help="Rewrite <run-dir>/checkpoint.pt every N steps.")
@click.option("--run-dir", type=click.Path(file_okay=False, path_type=Path), default=Path("runs/dualtalk-tiny"),
              show_default=True, help="Run folder for checkpoint.pt (rewritten every --save-every steps).")
@deprecated_alias("--out", "--run-dir", "run_dir", type=click.Path(file_okay=False, path_type=Path))
@click.option("--export", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="Weights file: also write the final checkpoint to this file (e.g. to ship or pass to "
                   "`dyadbench eval --weights`).")
@click.option("--device", default="cpu", show_default=True, help="cpu or cuda.")
def train_dualtalk(data: Path | None, dataset: str | None, clips: int | None, steps: int, batch_size: int, lr: float,
                   min_seconds: int, max_seconds: int, feature_dim: int | None, seed: int, save_every: int,
                   run_dir: Path, export: Path | None, device: str) -> None:
    """Train the log-mel DualTalk (tiny) on random 1-8 s windows; released loss, Adam.

    \b
    Reproduces the shipped checkpoints, one per embedded corpus (models/dualtalk/checkpoints/):
      OMP_NUM_THREADS=1 dyadbench train dualtalk --dataset synthetic --steps 2000 --lr 5e-4 --seed 0 \\
          --export models/dualtalk/checkpoints/dualtalk-tiny.pt
      OMP_NUM_THREADS=1 dyadbench train dualtalk --dataset synthetic-v2 --steps 2000 --lr 5e-4 --seed 0 \\
          --export models/dualtalk/checkpoints/dualtalk-tiny-v2.pt
    """
    from dyadbench.outputs import check_cache, check_file, check_folder  # noqa: PLC0415
    from models.dualtalk.config import preset  # noqa: PLC0415
    from models.dualtalk.train import TrainSettings, train_dualtalk_model  # noqa: PLC0415

    check_cache()
    check_folder(run_dir, f"--run-dir {run_dir}")
    if export is not None:
        check_file(export, f"--export {export}")
    cfg = preset("tiny", **({"feature_dim": feature_dim} if feature_dim else {}))
    source = open_train_split(data, dataset, clips)
    settings = TrainSettings(steps=steps, batch_size=batch_size, lr=lr, min_seconds=min_seconds,
                             max_seconds=max_seconds, seed=seed, save_every=save_every, device=device,
                             command=recorded_command() or "")
    click.echo(f"checkpoint: {train_dualtalk_model(cfg, source, run_dir, settings, export=export)}")
