"""``dyadbench plot``: trajectories of one prediction, metric-vs-context curves, per-model bars, the figure set.

Every figure is PDF, SVG or PNG by the extension of ``--out`` (another extension is refused before anything
is computed) in one style (:mod:`dyadbench.figure_style`)."""

from __future__ import annotations

from pathlib import Path

import click

from dyadbench.arrays import load_npy
from dyadbench.cli.eval import open_splits, resolve_dataset
from dyadbench.errors import InputError
from dyadbench.figure_style import FORMATS, figure_format
from dyadbench.outputs import check_cache, check_file, check_folder
from dyadbench.registry import DATASETS

FIGURE_HELP = "Figure file: .pdf, .svg or .png (the format follows the extension)."


def _figure_out(out: Path) -> None:
    figure_format(out)
    check_file(out, f"--out {out}")


@click.group()
def plot() -> None:
    """Figures for papers: trajectories, metrics against context, per-model bars, the whole set.

    \b
    Every figure is written as PDF, SVG or PNG by the extension of --out (another extension is an error),
    in one style sized for a two-column paper; every model keeps one colour and marker in every figure,
    baselines are thin grey lines, protocol variants (e.g. `timar (cfg1.5)`) are separate series, and a
    baseline far outside the models' range is drawn at the panel edge with its value written there.
    Regenerate the committed figures with
      dyadbench plot all results/ --robustness results-robustness --out figures/
    """


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
@click.option("--out", "out", required=True, type=click.Path(dir_okay=False, path_type=Path), help=FIGURE_HELP)
def trajectories(predictions: Path, clip_id: str, agent: str, data: Path | None, dataset: str | None,
                 split: str | None, dims: str | None, out: Path) -> None:
    """Prediction vs ground truth vs partner over time for one clip, one panel per dimension."""
    from dyadbench.motion import LAYOUTS  # noqa: PLC0415
    from dyadbench.plotting import parse_dims, plot_trajectories  # noqa: PLC0415

    _figure_out(out)
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


METRIC_OPTION = click.option("--metric", "metrics", multiple=True, default=None,
                             help="Metric key (repeatable), e.g. fd_exp, rpcc_jaw [default: the suite's figure "
                                  "metrics, e.g. fd_exp, pfd_exp, mse_exp for DualTalk].")
DATASET_OPTION = click.option("--dataset", default=None,
                              help="Dataset whose results to draw (required when RESULTS hold several; "
                                   "datasets never share a figure).")
RESULTS_ARGUMENT = click.argument("results", nargs=-1, required=True, type=click.Path(exists=True, path_type=Path))


def _rows(results: tuple[Path, ...], metrics: tuple[str, ...], dataset: str | None, uncertainty: bool):
    """The long table of RESULTS (with recorded CIs when ``uncertainty``) and the metrics to draw."""
    from dyadbench.figure_set import figure_metrics  # noqa: PLC0415
    from dyadbench.leaderboard import long_table  # noqa: PLC0415
    from dyadbench.leaderboard_uncertainty import with_uncertainty  # noqa: PLC0415

    long = long_table(results)
    if uncertainty:
        long = with_uncertainty(long)
    if not metrics:
        suites = sorted(set(long.loc[long["dataset"] == dataset, "suite"] if dataset else long["suite"]))
        metrics = tuple(m for suite in suites for m in figure_metrics(suite))
    return long, list(metrics)


@plot.command()
@RESULTS_ARGUMENT
@METRIC_OPTION
@DATASET_OPTION
@click.option("--out", "out", required=True, type=click.Path(dir_okay=False, path_type=Path), help=FIGURE_HELP)
def context(results: tuple[Path, ...], metrics: tuple[str, ...], dataset: str | None, out: Path) -> None:
    """Metrics (publication-scaled) against context n from RESULTS files/folders of one dataset: one panel
    per metric and split (splits with results at two or more contexts), one series per model and variant,
    x ticks at the contexts the results hold."""
    from dyadbench.plotting import plot_context_curves  # noqa: PLC0415

    _figure_out(out)
    long, metrics = _rows(results, metrics, dataset, uncertainty=False)
    click.echo(f"wrote {plot_context_curves(long, metrics, out, dataset)}")


@plot.command()
@RESULTS_ARGUMENT
@METRIC_OPTION
@DATASET_OPTION
@click.option("--context", "-n", "context", default=None, type=click.IntRange(min=0),
              help="Context n of the bars [default: the largest the results hold].")
@click.option("--out", "out", required=True, type=click.Path(dir_okay=False, path_type=Path), help=FIGURE_HELP)
def bars(results: tuple[Path, ...], metrics: tuple[str, ...], dataset: str | None, context: int | None,
         out: Path) -> None:
    """One bar per model and variant from RESULTS of one dataset at one context, best first, with the
    95 % bootstrap CI the result files record as error bars (none for results recorded without it)."""
    from dyadbench.plotting import plot_bars  # noqa: PLC0415

    _figure_out(out)
    long, metrics = _rows(results, metrics, dataset, uncertainty=True)
    click.echo(f"wrote {plot_bars(long, metrics, out, dataset, context)}")


@plot.command("all")
@RESULTS_ARGUMENT
@click.option("--robustness", "robustness", default=None, type=click.Path(exists=True, file_okay=False, path_type=Path),
              help="Robustness results folder (dyadbench robustness) to draw robustness.<ext> from.")
@click.option("--format", "formats", default="pdf,png", show_default=True,
              help=f"Comma-separated formats of every figure ({', '.join(e[1:] for e in FORMATS)}).")
@click.option("--out", "out", required=True, type=click.Path(file_okay=False, path_type=Path),
              help="Folder of the figure set.")
def all_figures(results: tuple[Path, ...], robustness: Path | None, formats: str, out: Path) -> None:
    """The paper's figure set from RESULTS (dyadbench.figure_set): per dataset context_<dataset> (when a
    split holds two or more contexts) and bars_<dataset>; robustness with --robustness. Figures of earlier
    builds in OUT that are not part of this one are removed, so OUT holds exactly this set."""
    from dyadbench.figure_set import check_formats, figure_builders, write_figures  # noqa: PLC0415

    kinds = check_formats(f.strip() for f in formats.split(",") if f.strip())
    check_folder(out, f"--out {out}")
    written, removed = write_figures(out, figure_builders(results, robustness), kinds)
    for path in written:
        click.echo(f"wrote {path}")
    for path in removed:
        click.echo(f"removed {path} (not part of this build)")
