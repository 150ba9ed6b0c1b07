"""``dyadbench plot``: trajectories of one prediction, and metric-vs-context curves (PNG)."""

from __future__ import annotations

from pathlib import Path

import click

from dyadbench.arrays import load_npy
from dyadbench.cli.eval import open_splits, resolve_dataset
from dyadbench.errors import InputError
from dyadbench.outputs import check_cache, check_file
from dyadbench.registry import DATASETS


@click.group()
def plot() -> None:
    """Plot predictions against ground truth, or metrics against the context length."""


@plot.command()
@click.argument("predictions", type=click.Path(exists=True, file_okay=False, path_type=Path))
@click.option("--clip", "clip_id", required=True, help="Clip id, e.g. synth_test_00000.")
@click.option("--agent", default="speaker1", show_default=True,
              help="Predicted participant: the file PREDICTIONS/<clip>_<agent>.npy is plotted.")
@click.option("--data", type=click.Path(exists=True, file_okay=False, path_type=Path), default=None,
              help="Dataset root holding the ground truth (default: the embedded synthetic corpus).")
@click.option("--dataset", default=None, type=click.Choice(DATASETS.names()),
              help="Dataset adapter (default: synthetic without --data, dualtalk with it).")
@click.option("--split", default=None,
              help="Split the clip belongs to [default: test; for a single split folder as --data, that folder].")
@click.option("--dims", default=None,
              help="Panels as component:index, e.g. exp:0,jaw:0,pose:1 (default: exp 0-1, jaw 0, pose 0-2; "
                   "gaze-head: head 0-2, gaze 0-3).")
@click.option("--out", "out", required=True, type=click.Path(dir_okay=False, path_type=Path), help="PNG file.")
def trajectories(predictions: Path, clip_id: str, agent: str, data: Path | None, dataset: str | None,
                 split: str | None, dims: str | None, out: Path) -> None:
    """Prediction vs ground truth vs partner over time for one clip, one panel per dimension."""
    from dyadbench.motion import LAYOUTS  # noqa: PLC0415
    from dyadbench.plotting import parse_dims, plot_trajectories  # noqa: PLC0415

    check_file(out, f"--out {out}")
    check_cache()
    path = predictions / f"{clip_id}_{agent}.npy"
    pred = load_npy(path)  # a missing, non-NumPy or pickled file is an InputError naming it
    source, _ = open_splits(data, resolve_dataset(data, dataset), split)
    clip = source.load(clip_id)
    try:
        gt = clip.participant(agent).motion
    except KeyError:
        raise InputError(path, f"{clip_id} has no participant {agent!r}") from None
    partner = clip.partner_of(agent)
    panels = parse_dims(dims, LAYOUTS[clip.layout]) if dims else None
    written = plot_trajectories(pred, gt, partner.motion if partner else None, clip.layout, out, fps=clip.fps,
                                dims=panels, title=f"{clip_id}_{agent}")
    click.echo(f"wrote {written}")


@plot.command()
@click.argument("results", nargs=-1, required=True, type=click.Path(exists=True, path_type=Path))
@click.option("--metric", "metrics", multiple=True, default=("fd_exp", "pfd_exp", "mse_exp"), show_default=True,
              help="Metric key to plot (repeatable), e.g. fd_exp, rpcc_jaw.")
@click.option("--out", "out", required=True, type=click.Path(dir_okay=False, path_type=Path), help="PNG file.")
def context(results: tuple[Path, ...], metrics: tuple[str, ...], out: Path) -> None:
    """Metric (publication-scaled) against context n, one line per model, from RESULTS files/folders."""
    from dyadbench.plotting import plot_context_curves  # noqa: PLC0415
    from dyadbench.results import results_frame  # noqa: PLC0415

    check_file(out, f"--out {out}")
    written = plot_context_curves(results_frame(results), list(metrics), out)
    click.echo(f"wrote {written}")
