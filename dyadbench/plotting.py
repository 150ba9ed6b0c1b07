"""PNG figures: per-clip trajectories and metric-vs-context curves (matplotlib, Agg backend).

- :func:`plot_trajectories`: prediction vs the agent's ground truth vs the partner's motion over time,
  one panel per selected dimension, grouped by motion component (exp / jaw / pose, or head / gaze).
- :func:`plot_context_curves`: a metric (publication-scaled) against the context length n, one line per
  model, one panel per dataset/split; oracle rows dashed and labelled as such.

matplotlib is imported only inside these functions, and files are written atomically.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from dyadbench import atomic
from dyadbench.errors import ConfigError
from dyadbench.motion import LAYOUTS, MotionLayout

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


def _save(fig, out: str | Path) -> Path:
    import matplotlib.pyplot as plt

    try:
        return atomic.write_with(out, lambda tmp: fig.savefig(tmp, format="png", dpi=110))
    finally:
        plt.close(fig)


def plot_trajectories(pred: np.ndarray, gt: np.ndarray, partner: np.ndarray | None, layout: str, out: str | Path,
                      *, fps: float = 25.0, dims: tuple[tuple[str, int], ...] | None = None,
                      title: str = "") -> Path:
    """Plot prediction, ground truth and partner (if any) for each selected dimension; write a PNG."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    spec = LAYOUTS[layout]
    dims = dims or DEFAULT_DIMS[layout]
    for name, arr in (("prediction", pred), ("ground truth", gt), ("partner", partner)):
        if arr is not None and (arr.ndim != 2 or arr.shape[1] != spec.dim):
            raise ConfigError(f"{name} must be (T, {spec.dim}) for layout {layout}, got {arr.shape}")
    fig, axes = plt.subplots(len(dims), 1, figsize=(10, 1.6 * len(dims) + 0.6), sharex=True, squeeze=False)
    for ax, (name, i) in zip(axes[:, 0], dims):
        column = spec.components[name].start + i
        for arr, label, style in ((gt, "ground truth", dict(color="black", lw=1.2)),
                                  (pred, "prediction", dict(color="tab:blue", lw=1.0)),
                                  (partner, "partner", dict(color="tab:orange", lw=0.8, ls="--", alpha=0.8))):
            if arr is not None:
                ax.plot(np.arange(arr.shape[0]) / fps, arr[:, column], label=label, **style)
        ax.set_ylabel(f"{name}[{i}]")
    axes[0, 0].legend(loc="upper right", fontsize=8, ncol=3)
    axes[-1, 0].set_xlabel("time (s)")
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    return _save(fig, out)


def plot_context_curves(long: pd.DataFrame, metrics: list[str], out: str | Path) -> Path:
    """Plot each metric (scaled) against context n from a long results table; write a PNG."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    data = long[long["metric"].isin(metrics) & long["context"].notna()]
    missing = [m for m in metrics if m not in set(data["metric"])]
    if missing:
        raise ConfigError(f"no results with context for metric(s) {', '.join(missing)}")
    groups = list(data.groupby(["dataset", "split"]))
    fig, axes = plt.subplots(len(metrics), len(groups), figsize=(4.5 * len(groups), 3.2 * len(metrics)),
                             squeeze=False)
    for col, ((dataset, split), part) in enumerate(groups):
        for row, metric in enumerate(metrics):
            ax = axes[row, col]
            for model, line in part[part["metric"] == metric].groupby("model"):
                line = line.sort_values("context")
                oracle = bool(line["oracle"].iloc[0])
                ax.plot(line["context"].astype(int), line["scaled"], marker="o", ls="--" if oracle else "-",
                        label=f"{model} (oracle)" if oracle else model)
            ax.set_title(f"{dataset} {split}: {metric}", fontsize=9)
            ax.set_xlabel("context n (history turns)")
            ax.set_ylabel(f"{metric} (scaled)")
            ax.legend(fontsize=7)
    fig.tight_layout()
    return _save(fig, out)
