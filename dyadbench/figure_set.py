"""The paper's figure set from result folders: what ``dyadbench plot all`` writes.

For every dataset of the results (datasets never share a figure; e.g. ``synthetic`` and ``synthetic-v2``
are separate files):

- ``context_<dataset>.<ext>``: :func:`dyadbench.plotting.plot_context_curves` of the suite's
  :data:`FIGURE_METRICS`, when some split holds results at two or more contexts;
- ``bars_<dataset>.<ext>``: :func:`dyadbench.plotting.plot_bars` of the same metrics at the largest context,
  with the results' recorded 95 % CIs;

and, from a robustness results folder, ``robustness.<ext>`` (:mod:`dyadbench.robustness_plot`). Each figure
is written once per requested format. The output folder afterwards holds exactly this set: figure files
of earlier builds that are not part of it (names matching :data:`FIGURE_NAMES`) are removed.
"""

from __future__ import annotations

from pathlib import Path
from typing import Callable, Iterable

import pandas as pd

from dyadbench.errors import ConfigError, InputError
from dyadbench.figure_style import FORMATS
from dyadbench.leaderboard import long_table
from dyadbench.leaderboard_uncertainty import with_uncertainty
from dyadbench.metrics.columns import declared

#: Metrics drawn per suite (the paper's headline columns); a suite not listed draws its primary column.
FIGURE_METRICS = {"dualtalk": ("fd_exp", "pfd_exp", "mse_exp"), "l2l": ("l2_exp", "fd_exp", "pfd_exp"),
                  "gaze": ("sim_gt", "mae_all", "bas_all"), "react": ("FRCorr",)}
#: File names of the figures a build writes (see :func:`write_figures`).
FIGURE_NAMES = tuple(f"{kind}{ext}" for kind in ("context_*", "bars_*", "robustness") for ext in FORMATS)


def figure_metrics(suite: str) -> list[str]:
    if suite in FIGURE_METRICS:
        return list(FIGURE_METRICS[suite])
    columns = declared(suite)
    if columns is None:
        raise ConfigError(f"suite {suite!r} declares no columns; plot it with `plot context/bars --metric`")
    return [columns.primary]


def figure_builders(results: Iterable[Path], robustness: Path | None = None
                    ) -> dict[str, Callable[[Path], Path]]:
    """Figure stem -> a function writing that figure to a given path (extension = format)."""
    from dyadbench import plotting  # noqa: PLC0415

    long = with_uncertainty(long_table(results))
    builders = {}
    for dataset in sorted(set(long["dataset"])):
        rows = long[long["dataset"] == dataset]
        suites = sorted(set(rows["suite"]))
        if len(suites) != 1:
            raise InputError(dataset, f"results of one dataset scored by several suites: {', '.join(suites)}")
        metrics = [m for m in figure_metrics(suites[0]) if m in set(rows["metric"])]
        if rows.groupby("split")["context"].nunique().max() > 1:
            builders[f"context_{dataset}"] = _bind(plotting.plot_context_curves, rows, metrics, dataset)
        builders[f"bars_{dataset}"] = _bind(plotting.plot_bars, rows, metrics, dataset)
    if robustness is not None:
        builders["robustness"] = _robustness(robustness)
    return builders


def _bind(plot, rows: pd.DataFrame, metrics: list[str], dataset: str) -> Callable[[Path], Path]:
    return lambda path: plot(rows, metrics, path, dataset)


def _robustness(folder: Path) -> Callable[[Path], Path]:
    from dyadbench.robustness import degradation_frame  # noqa: PLC0415
    from dyadbench.robustness_plot import plot_robustness  # noqa: PLC0415

    frame, _ = degradation_frame([folder])
    if frame.empty:
        raise InputError(folder, "no perturbed result with a clean run of the same configuration")
    return lambda path: plot_robustness(frame, path)


def figure_files(stems: Iterable[str], formats: Iterable[str]) -> list[str]:
    """The file names of a build: every stem in every format (``pdf`` -> ``.pdf``)."""
    return [f"{stem}.{fmt}" for stem in stems for fmt in formats]


def check_formats(formats: Iterable[str]) -> list[str]:
    """``formats`` as a list; ConfigError for none or for one that is not pdf, svg or png."""
    formats = list(formats)
    unknown = [f for f in formats if f".{f}" not in FORMATS]
    if unknown or not formats:
        raise ConfigError(f"unknown figure format(s) {', '.join(unknown) or '(none given)'}; use "
                          f"{', '.join(ext[1:] for ext in FORMATS)}")
    return formats


def write_figures(out: Path, builders: dict[str, Callable[[Path], Path]], formats: Iterable[str]
                  ) -> tuple[list[Path], list[Path]]:
    """Write every figure in every format into ``out`` and remove earlier builds' figures not in this one.

    Returns (written, removed)."""
    formats = check_formats(formats)
    out.mkdir(parents=True, exist_ok=True)
    written = [builders[stem](out / name) for stem in builders
               for name in figure_files([stem], formats)]
    stale = sorted({p for pattern in FIGURE_NAMES for p in out.glob(pattern) if p.is_file()} - set(written))
    for path in stale:
        path.unlink()
    return written, stale
