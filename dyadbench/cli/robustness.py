"""``dyadbench robustness``: the paper's robustness sweep per model, then the degradation table and plot."""

from __future__ import annotations

from pathlib import Path

import click

from dyadbench import atomic
from dyadbench.cli.eval import data_options, resolve_dataset, wav2vec_extra
from dyadbench.cli.options import POSITIVE, SEED
from dyadbench.cli.splits import open_splits
from dyadbench.cli.eval import run_variant
from dyadbench.cli.cluster import ClusterSweep, scheduler_option
from dyadbench.cli.sweep import _csv, result_path, runs_to_files
from dyadbench.errors import InputError
from dyadbench.outputs import check_cache, check_folder
from dyadbench.protocol.config import ProtocolConfig
from dyadbench.registry import MODELS
from dyadbench.robustness import LEVELS, TABLE_STEM, degradation_frame, sweep_settings, table_texts
from dyadbench.robustness_plot import plot_robustness


def _levels(text: str) -> list[float]:
    try:
        levels = [float(v) for v in _csv(text, "levels")]
    except ValueError:
        raise click.BadParameter(f"expected comma-separated numbers, got {text!r}", param_hint="--levels") from None
    if not all(0 < v <= 1 for v in levels):
        raise click.BadParameter("each occupancy must be in (0, 1]", param_hint="--levels")
    return levels


def write_report(results: Path, out: Path) -> list[Path]:
    """The degradation table (CSV, Markdown, LaTeX) and the plot of every result under ``results``, in ``out``."""
    frame, orphans = degradation_frame([results])
    for path in orphans:
        click.echo(f"left out {path}: no clean run of the same configuration", err=True)
    if frame.empty:
        raise InputError(results, "no perturbed result with a clean run of the same configuration")
    written = atomic.write_texts({out / name: text for name, text in table_texts(frame).items()})
    return written + [plot_robustness(frame, out / f"{TABLE_STEM}.png")]


@click.command()
@click.option("--models", default=None, help="Comma-separated registered models (required unless --table-only).")
@click.option("--split", default="test", show_default=True, help="Split to evaluate.")
@click.option("--context", "-n", default=7, show_default=True, type=click.IntRange(min=0),
              help="History turns n.")
@click.option("--levels", default=",".join(f"{v:g}" for v in LEVELS), show_default=True,
              help="Burst occupancies of each perturbation family.")
@click.option("--burst", "burst_s", default=1.0, show_default=True, type=POSITIVE, help="Mean burst length (s).")
@click.option("--seed", default=0, show_default=True, type=SEED, help="Run seed (models and perturbations).")
@click.option("--noise-scale", "noise_scale", default=None, type=POSITIVE,
              help="Motion-noise scale [default: the mean per-dimension std of the train split's motion].")
@click.option("--wav2vec", "wav2vec", default=None, type=click.Path(exists=True, file_okay=False, path_type=Path),
              help="Local wav2vec 2.0 folder for models with wav2vec speech features.")
@data_options
@click.option("--results", "results", type=click.Path(file_okay=False, path_type=Path),
              default=Path("results-robustness"), show_default=True,
              help="Result folder: RESULTS/<dataset>/<split>/n<context>/<model>[@<perturbation>].json.")
@click.option("--out", "out", type=click.Path(file_okay=False, path_type=Path), default=Path("leaderboards"),
              show_default=True, help="Folder of robustness.csv/.md/.tex and robustness.png.")
@click.option("--per-clip/--no-per-clip", default=True, show_default=True, help="Keep per-clip metrics.")
@click.option("--force", is_flag=True, help="Re-run runs whose result file holds the same configuration.")
@click.option("--table-only", is_flag=True, help="Run nothing: rebuild the table and plot from --results.")
@scheduler_option
def robustness(models: str | None, split: str, context: int, levels: str, burst_s: float, seed: int,
               noise_scale: float | None, wav2vec: Path | None, data: Path | None, dataset: str | None,
               train: Path | None, allow_train_overlap: bool, clips: int | None, jobs: int, threads: int | None,
               batch: int, results: Path, out: Path, per_clip: bool, force: bool, table_only: bool) -> None:
    """Run TIMAR's robustness sweep for each MODEL and write the degradation table and plot.

    \b
    Per model: the clean run, then partner motion drop (hold last frame) and gaussian noise, partner and
    agent speech silence and 60-dB noise, each at every --levels occupancy with --burst bursts, and the
    agent's speech silenced throughout; one result file each (a run with the same recorded configuration is
    skipped). The committed table and plot (first 40 test dialogues of the embedded corpus):
      M=zero,mean-frame,median-frame,random,mime,lagged-mirror,nn-retrieval
      dyadbench robustness --models $M,timar,timar-stream,sfms,dualtalk,dualtalk-offline \\
          --clips 40 --no-per-clip --jobs 1 --threads 1
    and they regenerate byte for byte from the result files with:
      dyadbench robustness --table-only --results results-robustness --out leaderboards/
    """
    check_folder(out, f"--out {out}")
    if not table_only:
        if models is None:
            raise click.UsageError("--models is required unless --table-only")
        names = _csv(models, "models")
        for name in names:
            MODELS.get(name)
        settings = sweep_settings(_levels(levels), burst_s)
        name_ = resolve_dataset(data, dataset)
        check_cache()
        check_folder(results, f"--results {results}")
        source, train_split = open_splits(data, name_, split, train=train, allow_overlap=allow_train_overlap)
        run_or_send = runs_to_files()  # with --scheduler: one task per run
        for name in names:
            for perturbations in settings:
                config = ProtocolConfig(context=context, seed=seed, perturbations=perturbations,
                                        noise_scale=noise_scale)
                path = result_path(results, name_, source.split, context, name, run_variant(config, 1.0))
                run_or_send(path, name, source, train_split, config, cfg_scale=1.0, weights=None, clips=clips,
                            jobs=jobs, threads=threads, extra=wav2vec_extra(wav2vec), force=force,
                            per_clip=per_clip, batch=batch)
        if isinstance(run_or_send, ClusterSweep):
            run_or_send.finish()
    for path in write_report(results, out):
        click.echo(f"wrote {path}")
