"""Figures from result files and predictions: context curves, per-model bars, trajectories.

- :func:`plot_context_curves`: metrics (publication-scaled, :mod:`dyadbench.metrics.columns`) against the
  context length n of one dataset; one panel per metric (rows) and split (columns), one series per model
  *and* protocol variant (``timar`` and ``timar (cfg1.5)`` are two series); the x ticks are the contexts the
  results hold. Splits with results at fewer than two contexts are left out (no one-point axes).
  A baseline far outside the models' range is drawn at the panel's edge with its value written there
  (:mod:`dyadbench.figure_range`).
- :func:`plot_bars`: one metric per panel row and split per column at one context, one horizontal bar per
  model and variant, best first by the metric's direction, with the 95 % bootstrap CI the result files
  record (:mod:`dyadbench.uncertainty`) as error bars where they record one. A baseline far outside the
  models' range is cut at the panel's edge with its value written on it; a bar too short to see (the
  oracle's 0) has its value written beside it.
- :func:`plot_trajectories`: prediction vs the agent's ground truth vs the partner's motion over time,
  one panel per selected dimension, grouped by motion component (exp / jaw / pose, or head / gaze).

Every figure uses :mod:`dyadbench.figure_style` (format by extension, paper sizes, one colour and marker per
model in every figure, baselines in grey, legend outside the panels). Rows of different datasets never share a figure.
matplotlib is imported only inside these functions, and files are written atomically.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from dyadbench import figure_style as style
from dyadbench.errors import ConfigError
from dyadbench.figure_range import ValueRange, off_scale_note, value_range
from dyadbench.leaderboard import variant_models
from dyadbench.metrics.columns import declared
from dyadbench.motion import LAYOUTS, MotionLayout
from dyadbench.registry import dataset_label

#: Default panels per layout: (component, index within the component).
DEFAULT_DIMS = {
    "flame56": (("exp", 0), ("exp", 1), ("jaw", 0), ("pose", 0), ("pose", 1), ("pose", 2)),
    "gaze7": (("head", 0), ("head", 1), ("head", 2), ("gaze", 0), ("gaze", 1), ("gaze", 2), ("gaze", 3)),
}


def parse_dims(text: str, layout: MotionLayout) -> tuple[tuple[str, int], ...]:
    """``"exp:0,jaw:0,pose:1"`` -> (("exp", 0), ("jaw", 0), ("pose", 1)), checked against ``layout``."""
    dims = []
    for part in (p.strip() for p in text.split(",") if p.strip()):
        name, _, index = part.partition(":")
        if name not in layout.components:
            raise ConfigError(f"unknown component {name!r} in --dims (layout {layout.name} has "
                              f"{', '.join(layout.components)})")
        comp = layout.components[name]
        size = comp.stop - comp.start
        try:
            i = int(index)
        except ValueError:
            raise ConfigError(f"--dims entries are component:index, got {part!r}") from None
        if not 0 <= i < size:
            raise ConfigError(f"{name} has {size} dims; index {i} is out of range")
        dims.append((name, i))
    if not dims:
        raise ConfigError("--dims selected nothing")
    return tuple(dims)


def axis_label(suite: str, metric: str) -> str:
    """A metric's printed header with its direction and scale, e.g. ``FD exp ↓ (x10)``; the key when
    its suite does not declare it."""
    columns = declared(suite)
    spec = None if columns is None else columns.spec(metric)
    if spec is None:
        return metric
    arrow = {True: " ↑", False: " ↓", None: ""}[spec.higher_is_better]
    scale = spec.scale_label()
    return f"{spec.header}{arrow}" + (f" ({scale})" if scale else "")


def plot_trajectories(pred: np.ndarray, gt: np.ndarray, partner: np.ndarray | None, layout: str, out: str | Path,
                      *, fps: float = 25.0, dims: tuple[tuple[str, int], ...] | None = None,
                      title: str = "") -> Path:
    """Plot prediction, ground truth and partner (if any) for each selected dimension; write ``out``
    (PDF, SVG or PNG by extension)."""
    style.figure_format(out)
    spec = LAYOUTS[layout]
    dims = dims or DEFAULT_DIMS[layout]
    for name, arr in (("prediction", pred), ("ground truth", gt), ("partner", partner)):
        if arr is not None and (arr.ndim != 2 or arr.shape[1] != spec.dim):
            raise ConfigError(f"{name} must be (T, {spec.dim}) for layout {layout}, got {arr.shape}")
    with style.paper_style() as plt:
        fig, axes = plt.subplots(len(dims), 1, figsize=(style.PAGE_WIDTH, 0.9 * len(dims) + 0.5), sharex=True,
                                 squeeze=False, layout="constrained")
        for ax, (name, i) in zip(axes[:, 0], dims):
            column = spec.components[name].start + i
            for arr, label, kwargs in ((gt, "ground truth", dict(color="black", lw=1.1)),
                                       (pred, "prediction", dict(color=style.BRIGHT["blue"], lw=0.9)),
                                       (partner, "partner", dict(color=style.BRIGHT["red"], lw=0.8, ls="--"))):
                if arr is not None:
                    ax.plot(np.arange(arr.shape[0]) / fps, arr[:, column], label=label, **kwargs)
            ax.set_ylabel(f"{name}[{i}]")
        axes[-1, 0].set_xlabel("time (s)")
        if title:
            fig.suptitle(title)
        style.legend_outside(fig, axes[:, 0])
        return style.save(fig, out)


def labelled(long: pd.DataFrame, dataset: str | None, metrics: list[str]) -> pd.DataFrame:
    """The dyadbench rows of one dataset and of ``metrics`` from a leaderboard long table
    (:func:`dyadbench.leaderboard.long_table`), with ``label`` = model and protocol variant.

    ``dataset`` may be None when the rows hold a single dataset; ConfigError when they hold several (rows
    of different datasets never share a figure) or when a metric has no row."""
    rows = long[long["source"] == "dyadbench"]
    datasets = sorted(set(rows["dataset"]))
    if dataset is None and len(datasets) > 1:
        raise ConfigError(f"the results hold several datasets ({', '.join(datasets)}); choose one with --dataset")
    if dataset is not None and dataset not in datasets:
        raise ConfigError(f"no results of dataset {dataset!r} (they hold {', '.join(datasets) or 'none'})")
    rows = rows[rows["dataset"] == (dataset or datasets[0])] if datasets else rows
    rows = rows[rows["metric"].isin(metrics)]
    missing = [m for m in metrics if m not in set(rows["metric"])]
    if missing:
        raise ConfigError(f"no results for metric(s) {', '.join(missing)}")
    return rows.assign(label=variant_models(rows))


def series_of(rows: pd.DataFrame) -> list[tuple[str, bool]]:
    """The (label, oracle) series of :func:`labelled` rows, in legend order (:func:`figure_style.series_order`)."""
    pairs = {(label, bool(oracle)) for label, oracle in zip(rows["label"], rows["oracle"])}
    return sorted(pairs, key=lambda item: style.series_order(*item))


def trivial_labels(series: list[tuple[str, bool]], styles: dict[str, style.SeriesStyle]) -> set[str]:
    """Labels drawn as baselines: the series that may go off-scale (:mod:`dyadbench.figure_range`)."""
    return {label for label, _ in series if styles[label].kind == "baseline"}


def _grid(plt, rows: int, cols: int, panel: tuple[float, float]):
    width = min(style.PAGE_WIDTH, panel[0] * cols + 1.5)
    return plt.subplots(rows, cols, figsize=(width, panel[1] * rows + 0.3), squeeze=False, layout="constrained")


def plot_context_curves(long: pd.DataFrame, metrics: list[str], out: str | Path, dataset: str | None = None) -> Path:
    """Each metric (scaled) against context n, one series per model and variant, for one dataset; write
    ``out`` (PDF, SVG or PNG by extension). See the module docstring."""
    style.figure_format(out)
    data = labelled(long[long["context"].notna()], dataset, metrics)
    contexts = data.groupby("split")["context"].nunique()
    splits = sorted(contexts[contexts > 1].index)
    if not splits:
        raise ConfigError(f"{data['dataset'].iloc[0]} has results at one context only "
                          f"(n = {', '.join(map(str, sorted(set(data['context']))))}); plot them with `plot bars`")
    series = series_of(data)
    styles = style.figure_styles(series)
    trivial = trivial_labels(series, styles)
    with style.paper_style() as plt:
        fig, axes = _grid(plt, len(metrics), len(splits), (2.3, 1.6))
        for col, split in enumerate(splits):
            part = data[data["split"] == split]
            ticks = sorted(int(n) for n in set(part["context"]))
            for row, metric in enumerate(metrics):
                ax = axes[row, col]
                rows = part[part["metric"] == metric].dropna(subset=["scaled"])
                lines = {label: line.sort_values("context") for label, line in rows.groupby("label")}
                if not lines:
                    _no_data(ax, metric)
                    continue
                scale = value_range({label: line["scaled"] for label, line in lines.items()}, trivial)
                low, high = scale.limits()
                for label, oracle in series:
                    if label not in lines:
                        continue
                    line = lines[label]
                    name = label + (" (oracle)" if oracle and label != "oracle" else "")
                    off = label in scale.above or label in scale.below
                    ax.plot(line["context"].astype(int), line["scaled"].clip(low, high), label=name,
                            clip_on=not off, **styles[label].kwargs())
                ax.set_ylim(low, high)
                _note_off_scale(ax, scale)
                ax.set_xticks(ticks)
                ax.set_xlim(ticks[0] - 0.5, ticks[-1] + 0.5)
                if row == 0:
                    ax.set_title(f"{dataset_label(data['dataset'].iloc[0])} {split}")
                if row == len(metrics) - 1:
                    ax.set_xlabel("context n (history turns)")
                if col == 0:
                    ax.set_ylabel(axis_label(rows["suite"].iloc[0], metric))
        style.legend_outside(fig, axes.ravel())
        return style.save(fig, out)


def _no_data(ax, metric: str) -> None:
    ax.text(0.5, 0.5, f"no {metric} results", ha="center", va="center", transform=ax.transAxes)
    ax.set_axis_off()


def _note_off_scale(ax, scale: ValueRange) -> None:
    """Write the off-scale series' values in the band at the top and bottom of a panel."""
    for off, arrow, y, va in ((scale.above, "↑", 0.965, "top"), (scale.below, "↓", 0.035, "bottom")):
        if off:
            ax.text(0.99, y, off_scale_note(off, arrow), transform=ax.transAxes, ha="right", va=va, fontsize=6,
                    color="#333333")


def plot_bars(long: pd.DataFrame, metrics: list[str], out: str | Path, dataset: str | None = None,
              context: int | None = None) -> Path:
    """One bar per model and variant for each metric (rows) and split (columns) at one context (default:
    the largest the dataset's results hold), best first (the oracle last), variants hatched, with the
    recorded 95 % CI as error bars; write
    ``out`` (PDF, SVG or PNG by extension). ``long`` may carry ``ci_low`` / ``ci_high``
    (:func:`dyadbench.leaderboard_uncertainty.with_uncertainty`). A bar scored on other predictions than
    the panel's most common set is labelled with its number of items; the oracle is marked †."""
    style.figure_format(out)
    data = labelled(long, dataset, metrics)
    contexts = sorted(int(n) for n in set(data["context"].dropna()))
    if context is None and contexts:
        context = contexts[-1]
    if context is not None:
        if context not in contexts:
            raise ConfigError(f"no results at context n = {context} (they hold n = {', '.join(map(str, contexts))})")
        data = data[data["context"] == context]
    splits = sorted(set(data["split"]))
    series = series_of(data)
    styles = style.figure_styles(series)
    with style.paper_style() as plt:
        fig, axes = _grid(plt, len(metrics), len(splits), (2.3, 0.5 + 0.14 * len(series)))
        for col, split in enumerate(splits):
            for row, metric in enumerate(metrics):
                rows = data[(data["split"] == split) & (data["metric"] == metric)]
                _bars(axes[row, col], rows, metric, styles, trivial_labels(series, styles))
                title = f"{dataset_label(data['dataset'].iloc[0])} {split}" + (
                    f", n = {context}" if context is not None else "")
                axes[row, col].set_title(title if row == 0 else "")
        return style.save(fig, out)


def _bars(ax, rows: pd.DataFrame, metric: str, styles: dict[str, style.SeriesStyle], trivial: set[str]) -> None:
    rows = rows.dropna(subset=["scaled"])
    if rows.empty:
        _no_data(ax, metric)
        return
    higher = rows["higher_is_better"].iloc[0]
    rows = rows.sort_values(["oracle", "scaled"], ascending=[True, higher is False], kind="stable")
    scale = value_range(dict(zip(rows["label"], ([v] for v in rows["scaled"]))), trivial)
    tiny = 1e-6 * (scale.high - scale.low)  # rounding noise, e.g. the oracle's FD of 1e-13
    low, high = scale.limits()
    low, high = (0.0 if scale.low >= -tiny else low), (0.0 if scale.high <= tiny else high)
    common = rows["items"].mode()
    y = np.arange(len(rows))[::-1]
    for yi, (_, r) in zip(y, rows.iterrows()):
        series = styles[r["label"]]
        variant = series.linestyle != "-"  # variants and the oracle: hatched
        off = r["label"] in scale.above or r["label"] in scale.below
        value = float(np.clip(r["scaled"], low, high)) if off else float(r["scaled"])
        ax.barh(yi, value, color=series.color, hatch="////" if variant else None, edgecolor="white", lw=0.3)
        low_ci, high_ci = r.get("ci_low", np.nan), r.get("ci_high", np.nan)
        if off:  # cut at the edge, its value written on the bar
            note = f" {r['scaled']:.3g} → " if value > 0 else f" ← {r['scaled']:.3g} "
            ax.text(value, yi, note, ha="right" if value > 0 else "left", va="center", fontsize=6,
                    color=_ink(series.color))
        elif pd.notna(low_ci) and pd.notna(high_ci):
            ax.errorbar(value, yi, xerr=[[value - low_ci], [high_ci - value]], color="black", lw=0.7, capsize=1.5)
        elif abs(value) < 0.02 * (high - low):  # too short to see: its value beside it
            ax.text(max(value, 0.0) + 0.01 * (high - low), yi, f"{0.0 if abs(value) <= tiny else value:.3g}",
                    va="center", fontsize=6)
    names = [r["label"] + ("†" if r["oracle"] else "") + ("" if common.empty or r["items"] == common.iloc[0]
                                                           else f" ({int(r['items'])} items)")
             for _, r in rows.iterrows()]
    ax.set_yticks(y, names)
    ax.set_xlim(low, high)
    ax.set_xlabel(axis_label(rows["suite"].iloc[0], metric))
    ax.axvline(0.0, color="grey", lw=0.5)


def _ink(colour: str) -> str:
    """Black or white, whichever reads better on ``colour`` (relative luminance above or below 0.4)."""
    from matplotlib.colors import to_rgb  # noqa: PLC0415

    red, green, blue = to_rgb(colour)
    return "black" if 0.2126 * red + 0.7152 * green + 0.0722 * blue > 0.4 else "white"
