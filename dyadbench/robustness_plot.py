"""The robustness figure: increase over the clean run against burst occupancy, from the degradation table.

One panel per perturbation family (columns) and metric family (rows: P-FD, FD, MSE), one line per model;
the y value is the mean over the exp, jaw and pose components of the relative increase in %
(:func:`dyadbench.robustness.degradation_frame`), on a symmetric-log axis (linear within +-10 %), since a
partner-copying model's increase under motion noise is orders of magnitude above the others'. The clean run is
the point (0, 0); each model keeps its colour in every panel. Written without the PNG's software tag, so the
same table gives the same bytes.
"""

from __future__ import annotations

from pathlib import Path

import pandas as pd

from dyadbench import atomic
from dyadbench.robustness import METRICS, caption


def plot_robustness(frame: pd.DataFrame, out: str | Path) -> Path:
    """Write the figure (see the module docstring) of ``frame`` to ``out`` (PNG)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    families = sorted(set(frame["perturbation"]))
    colours = {model: f"C{i % 10}" for i, model in enumerate(sorted(set(frame["model"])))}
    fig, axes = plt.subplots(len(METRICS), len(families), figsize=(3.1 * len(families), 2.6 * len(METRICS)),
                             squeeze=False, sharex=True)
    for col, family in enumerate(families):
        part = frame[frame["perturbation"] == family]
        for row, (title, prefix) in enumerate(METRICS):
            ax = axes[row, col]
            rows = part[part["metric"].str.startswith(prefix + "_")]
            mean = rows.groupby(["model", "occupancy"])["increase_pct"].mean().reset_index()
            for model, line in mean.groupby("model", sort=True):
                ax.plot([0.0, *line["occupancy"]], [0.0, *line["increase_pct"]], marker="o", ms=3, label=model,
                        color=colours[model])
            ax.axhline(0.0, color="grey", lw=0.5)
            ax.set_yscale("symlog", linthresh=10)
            values = mean["increase_pct"].dropna()
            ax.set_ylim(min(-10.0, 1.5 * min(values, default=0.0)), max(10.0, 1.5 * max(values, default=0.0)))
            if row == 0:
                ax.set_title(family, fontsize=9)
            if row == len(METRICS) - 1:
                ax.set_xlabel("burst occupancy")
            if col == 0:
                ax.set_ylabel(f"{title} increase (%)")
    handles = [matplotlib.lines.Line2D([], [], color=c, marker="o", ms=3) for c in colours.values()]
    fig.legend(handles, list(colours), loc="lower center", ncol=len(colours), fontsize=8)
    fig.suptitle(f"Increase over clean, mean of exp/jaw/pose; {caption(frame)}", fontsize=9)
    fig.tight_layout(rect=(0, 0.05, 1, 1))
    try:
        return atomic.write_with(out, lambda tmp: fig.savefig(tmp, format="png", dpi=100,
                                                              metadata={"Software": None}))
    finally:
        plt.close(fig)
