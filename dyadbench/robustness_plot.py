"""The robustness figure: increase over the clean run against burst occupancy, from the degradation table.

One panel per perturbation family (columns) and metric family (rows: P-FD, FD, MSE), one line per model;
the y value is the mean over the exp, jaw and pose components of the relative increase in %
(:func:`dyadbench.robustness.degradation_frame`). The clean run is the point (0, 0). Written without the
PNG's software tag, so the same table gives the same bytes.
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
    fig, axes = plt.subplots(len(METRICS), len(families), figsize=(3.1 * len(families), 2.6 * len(METRICS)),
                             squeeze=False, sharex=True)
    for col, family in enumerate(families):
        part = frame[frame["perturbation"] == family]
        for row, (title, prefix) in enumerate(METRICS):
            ax = axes[row, col]
            rows = part[part["metric"].str.startswith(prefix + "_")]
            mean = rows.groupby(["model", "occupancy"])["increase_pct"].mean().reset_index()
            for model, line in mean.groupby("model", sort=True):
                ax.plot([0.0, *line["occupancy"]], [0.0, *line["increase_pct"]], marker="o", ms=3, label=model)
            ax.axhline(0.0, color="grey", lw=0.5)
            if row == 0:
                ax.set_title(family, fontsize=9)
            if row == len(METRICS) - 1:
                ax.set_xlabel("burst occupancy")
            if col == 0:
                ax.set_ylabel(f"{title} increase (%)")
    axes[0, -1].legend(fontsize=7)
    fig.suptitle(f"Increase over clean, mean of exp/jaw/pose; {caption(frame)}", fontsize=9)
    fig.tight_layout()
    try:
        return atomic.write_with(out, lambda tmp: fig.savefig(tmp, format="png", dpi=100,
                                                              metadata={"Software": None}))
    finally:
        plt.close(fig)
