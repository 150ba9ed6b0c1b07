"""The robustness figure: increase over the clean run against burst occupancy, from the degradation table.

One panel per perturbation family (columns) and metric family (rows: P-FD, FD, MSE), one line per model;
the y value is the mean over the exp, jaw and pose components of the relative increase in %
(:func:`dyadbench.robustness.degradation_frame`), on a symmetric-log axis (linear within +-10 %), since a
partner-copying model's increase under motion noise is orders of magnitude above the others'. The clean run is
the point (0, 0); the x ticks are the occupancies the sweep ran. Each model has its colour and marker of
every dyadbench figure, baselines in grey (:mod:`dyadbench.figure_style`); the legend is right of the panels.
Written as PDF, SVG or PNG by the extension of ``out``, without timestamps or software tags, so the same table
gives the same bytes.
"""

from __future__ import annotations

from pathlib import Path

import pandas as pd

from dyadbench import figure_style as style
from dyadbench.robustness import METRICS, caption


def plot_robustness(frame: pd.DataFrame, out: str | Path) -> Path:
    """Write the figure (see the module docstring) of ``frame`` to ``out``."""
    style.figure_format(out)
    families = sorted(set(frame["perturbation"]))
    styles = style.figure_styles((model, False) for model in set(frame["model"]))
    with style.paper_style() as plt:
        fig, axes = plt.subplots(len(METRICS), len(families), figsize=(style.PAGE_WIDTH, 1.35 * len(METRICS) + 0.5),
                                 squeeze=False, layout="constrained")
        for col, family in enumerate(families):
            part = frame[frame["perturbation"] == family]
            ticks = sorted({0.0, *part["occupancy"]})
            for row, (title, prefix) in enumerate(METRICS):
                ax = axes[row, col]
                rows = part[part["metric"].str.startswith(prefix + "_")]
                mean = rows.groupby(["model", "occupancy"])["increase_pct"].mean().reset_index()
                for model, series in styles.items():
                    line = mean[mean["model"] == model]
                    if not line.empty:
                        ax.plot([0.0, *line["occupancy"]], [0.0, *line["increase_pct"]], label=model,
                                **series.kwargs())
                ax.axhline(0.0, color="grey", lw=0.5)
                ax.set_yscale("symlog", linthresh=10)
                values = mean["increase_pct"].dropna()
                ax.set_ylim(min(-10.0, 1.5 * min(values, default=0.0)), max(10.0, 1.5 * max(values, default=0.0)))
                ax.set_xticks(ticks, _tick_labels(ticks))
                if row == 0:
                    ax.set_title(family.replace(" ", "\n", 1))
                if col == 0:
                    ax.set_ylabel(f"{title} increase (%)")
        fig.supxlabel("burst occupancy")
        style.legend_outside(fig, axes.ravel())
        fig.suptitle(f"Increase over clean, mean of exp/jaw/pose\n{caption(frame)}")
        return style.save(fig, out)


def _tick_labels(ticks: list[float], gap: float = 0.25) -> list[str]:
    """Occupancy tick labels (``.3``); a tick closer than ``gap`` to the previous labelled one is unlabelled."""
    labels, last = [], None
    for t in ticks:
        show = last is None or t - last >= gap
        labels.append((f"{t:g}".removeprefix("0") or "0") if show else "")
        last = t if show else last
    return labels
