"""The context-headroom result as Markdown and as a plot, both rendered from the result's ``data`` alone.

``data`` is what ``benchmarks/bench_context_headroom.py`` records: ``{"design": {...}, "corpora": {dataset:
measure(...)}}`` (:func:`dyadbench.headroom.estimate.measure`). :func:`render` gives the tables (one per
corpus and split: a row per n, scaled MSE / P-FD / FD per component with the relative change against n = 0)
and the target check; :func:`plot` the figure (relative change against n per metric and component, one line
per corpus and split, 95 % bootstrap band). Same data, same bytes: the Markdown holds no timestamp.
"""

from __future__ import annotations

from pathlib import Path

from dyadbench import atomic
from dyadbench.headroom.scores import KEYS
from dyadbench.motion import FLAME_COMPONENTS

HEADERS = {"mse": "MSE", "pfd": "P-FD", "fd": "FD"}
#: The issue's target: at n = 7 on test, these scaled metrics at least 10 % below n = 0.
TARGET_KEYS = ("pfd_exp", "mse_exp")
TARGET_CHANGE = -0.10
TARGET_SPLIT = "test"
TARGET_CONTEXT = "7"
PLOTTED = ("mse", "pfd")


def _percent(change: float) -> str:
    return f"{100 * change:+.1f} %".replace("-", "−")


def _interval(values: list[float]) -> str:
    change, low, high = values
    return f"{_percent(change)} [{_percent(low)}, {_percent(high)}]"


def split_table(split: dict) -> list[str]:
    """A row per n: each scaled metric, with its change against n = 0 for n > 0."""
    header = "| n | " + " | ".join(f"{HEADERS[k.split('_')[0]]} {k.split('_')[1]}" for k in KEYS) + " |"
    lines = [header, "|---" * (len(KEYS) + 1) + "|"]
    for n, means in split["means"].items():
        cells = [f"{means[k]:.4g}" + ("" if n == "0" else f" ({_percent(split['change'][n][k][0])})") for k in KEYS]
        lines.append(f"| {n} | " + " | ".join(cells) + " |")
    return lines


def target_lines(corpora: dict) -> list[str]:
    """The issue's target (n = 7 vs n = 0 on test, P-FD exp and MSE exp at least 10 % lower) per corpus."""
    lines = []
    for name, corpus in corpora.items():
        split = corpus["splits"].get(TARGET_SPLIT)
        if split is None:
            continue
        changes = {k: split["change"][TARGET_CONTEXT][k] for k in TARGET_KEYS}
        met = all(c[0] <= TARGET_CHANGE for c in changes.values())
        shown = "; ".join(f"{HEADERS[k.split('_')[0]]} {k.split('_')[1]} {_interval(c)}" for k, c in changes.items())
        lines.append(f"- {name}: {shown} — target {'met' if met else 'not met'}")
    return lines


def render(data: dict) -> str:
    """The result's Markdown (see the module docstring)."""
    design = data["design"]
    parts = ["# Context headroom: how much the visible history can lower the error (model-free)", "",
             design["summary"], "",
             f"Target (issue #25): at n = {TARGET_CONTEXT} on {TARGET_SPLIT}, P-FD exp and MSE exp at least "
             f"{-100 * TARGET_CHANGE:.0f} % below n = 0 (change [95 % dialogue-bootstrap interval]):", "",
             *target_lines(data["corpora"]), ""]
    for name, corpus in data["corpora"].items():
        clips = ", ".join(f"{c} {s}" for s, c in corpus["clips"].items())
        penalties = "; ".join(f"n = {n}: " + ", ".join(f"{c} λ {p['penalty'][c]:.3g}, r {p['history_ratio'][c]:g}"
                                                      for c in FLAME_COMPONENTS)
                              for n, p in corpus["fit"].items() if n in ("0", TARGET_CONTEXT))
        parts += [f"## {name}", "",
                  f"Clips: {clips} (train rows {corpus['rows']['train']}, val rows {corpus['rows']['val']}). "
                  f"Penalty λ and history ratio r chosen on val: {penalties}.", ""]
        for split_name, split in corpus["splits"].items():
            parts += [f"### {name} {split_name} ({split['predictions']} predictions, {split['dialogues']} "
                      f"dialogues): scaled as published, change against n = 0", "", *split_table(split), ""]
    parts.append(f"Plot: `{design['plot']}`.")
    return "\n".join(parts) + "\n"


def plot(data: dict, out: str | Path) -> Path:
    """Relative change against n = 0 (%) for MSE and P-FD (rows) per component (columns); write a PNG."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(len(PLOTTED), len(FLAME_COMPONENTS), figsize=(12, 6.5), squeeze=False)
    for row, metric in enumerate(PLOTTED):
        for col, component in enumerate(FLAME_COMPONENTS):
            ax, key = axes[row, col], f"{metric}_{component}"
            for name, corpus in data["corpora"].items():
                for split_name, split in corpus["splits"].items():
                    ns = [int(n) for n in split["change"]]
                    values = [100 * split["change"][str(n)][key][i] for i in range(3) for n in ns]
                    mid, low, high = (values[i * len(ns):(i + 1) * len(ns)] for i in range(3))
                    line, = ax.plot(ns, mid, marker="o", ls="-" if split_name == TARGET_SPLIT else "--",
                                    label=f"{name} {split_name}")
                    ax.fill_between(ns, low, high, color=line.get_color(), alpha=0.15)
            if metric + "_" + component in TARGET_KEYS:
                ax.axhline(100 * TARGET_CHANGE, color="grey", lw=0.8, ls=":")
            ax.axhline(0, color="black", lw=0.6)
            ax.set_title(f"{HEADERS[metric]} {component}", fontsize=10)
            ax.set_xlabel("context n (history turns)")
            ax.set_ylabel("change vs n = 0 (%)")
    axes[0, 0].legend(fontsize=8)
    fig.tight_layout()
    try:
        return atomic.write_with(out, lambda tmp: fig.savefig(tmp, format="png", dpi=100))
    finally:
        plt.close(fig)


def save_texts(files: dict[Path, str]) -> None:
    """Write re-rendered result files as one set (:func:`dyadbench.atomic.write_texts`)."""
    atomic.write_texts(files)
