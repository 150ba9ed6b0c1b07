"""The robustness sweep (TIMAR's Figure 9 as a benchmark axis) and its degradation table, from result files.

:func:`sweep_settings` lists the runs of the paper's sweep: the clean run, then for each perturbation family
(:data:`FAMILIES`: partner motion drop and gaussian noise, partner and agent speech silence and 60-dB noise)
the occupancies :data:`LEVELS` with 1-s bursts, and the agent's speech silenced throughout (occupancy 1,
4-s bursts, as released). ``dyadbench robustness`` runs them (one result file each, :mod:`dyadbench.cli.sweep`
variant names) and writes the table and the plot.

:func:`degradation_frame` pairs every perturbed result (one perturbation) with the clean result of the same
configuration (model, weights, data and its digest, clips, protocol settings, seed: the recorded
configuration less the perturbation, its noise scale and the train split, which motion noise opens) and
gives, per metric of :data:`METRICS`, the clean and perturbed values, the increase (perturbed - clean) and
the relative increase in % (100 · increase / clean). :func:`table_texts` renders it as CSV (every number),
Markdown and LaTeX (relative increases "exp / jaw / pose" per occupancy, one table per metric family).
"""

from __future__ import annotations

import io
import json
import math
from collections.abc import Iterable
from pathlib import Path

import pandas as pd

from dyadbench.errors import InputError
from dyadbench.leaderboard import latex_escape
from dyadbench.protocol.perturbations import Perturbation, parse_all
from dyadbench.results import load_result, result_files

LEVELS = (0.1, 0.3, 0.5, 0.7)
BURST_S = 1.0
FAMILIES = (("partner-motion", "drop"), ("partner-motion", "gaussian"), ("partner-speech", "silence"),
            ("partner-speech", "noise"), ("agent-speech", "silence"), ("agent-speech", "noise"))
#: The release's extreme: the agent's own speech silenced throughout.
AGENT_SILENCED = Perturbation("agent-speech", "silence", 1.0, 4.0)
#: Metric families (table title, result-metric prefix) and motion components.
METRICS = (("P-FD", "pfd"), ("FD", "fd"), ("MSE", "mse"))
COMPONENTS = ("exp", "jaw", "pose")
#: Configuration keys a perturbed run may differ in from its clean run.
PERTURBATION_KEYS = ("perturbations", "noise_scale", "train")
CSV_COLUMNS = ["model", "dataset", "split", "context", "clips", "perturbation", "occupancy", "burst_s", "metric",
               "clean", "perturbed", "increase", "increase_pct", "noise_scale", "file"]
TABLE_STEM = "robustness"


def sweep_settings(levels: Iterable[float] = LEVELS, burst_s: float = BURST_S) -> list[tuple[Perturbation, ...]]:
    """The perturbation tuples of the sweep: clean, each family at each level, the agent silenced throughout."""
    runs: list[tuple[Perturbation, ...]] = [()]
    runs += [(Perturbation(target, kind, level, burst_s),) for target, kind in FAMILIES for level in levels]
    return runs + [(AGENT_SILENCED,)]


def _clean_key(configuration: dict) -> str:
    return json.dumps({k: v for k, v in configuration.items() if k not in PERTURBATION_KEYS}, sort_keys=True)


def degradation_frame(paths: Iterable[str | Path]) -> tuple[pd.DataFrame, list[str]]:
    """The long degradation table (:data:`CSV_COLUMNS`) of every perturbed result under ``paths`` with a clean
    run, and the perturbed files without one (left out). Files recording no configuration are an error."""
    clean: dict[str, object] = {}
    perturbed = []
    for path in result_files(paths):
        result = load_result(path)
        if result.configuration is None:
            raise InputError(path, "records no configuration, so its clean run cannot be found; re-run it")
        key = _clean_key(result.configuration)
        if not result.protocol.perturbations:
            if key in clean:
                raise InputError(path, f"the same clean run as {clean[key][0]}")
            clean[key] = (path, result)
        else:
            perturbed.append((path, key, result))
    rows, orphans = [], []
    for path, key, result in perturbed:
        if key not in clean:
            orphans.append(str(path))
            continue
        found = parse_all(result.protocol.perturbations)
        if len(found) != 1:
            raise InputError(path, f"a robustness row has one perturbation, this run has {len(found)}")
        rows += _rows(found[0], result, clean[key][1], str(path))
    frame = pd.DataFrame(rows, columns=CSV_COLUMNS)
    return frame.sort_values(["dataset", "split", "context", "model", "perturbation", "occupancy", "burst_s",
                              "metric"], kind="stable").reset_index(drop=True), orphans


def _rows(p: Perturbation, result, reference, file: str) -> list[dict]:
    rows = []
    for _, prefix in METRICS:
        for component in COMPONENTS:
            metric = f"{prefix}_{component}"
            base, value = reference.metrics.get(metric, math.nan), result.metrics.get(metric, math.nan)
            rows.append({"model": result.model.name, "dataset": result.data.dataset, "split": result.data.split,
                         "context": result.protocol.context, "clips": result.data.clips, "perturbation": p.family,
                         "occupancy": p.occupancy, "burst_s": p.burst_s, "metric": metric, "clean": base,
                         "perturbed": value, "increase": value - base,
                         "increase_pct": 100 * (value - base) / base if base else math.nan,
                         "noise_scale": result.protocol.noise_scale, "file": file})
    return rows


def caption(frame: pd.DataFrame) -> str:
    """What the table covers, e.g. ``synthetic/test, n = 7, 40 clips (...); motion noise sigma = 0.26``."""
    parts = sorted({f"{d}/{s}, n = {n}, {c} clips (the first of the split, sorted ids)"
                    for d, s, n, c in frame[["dataset", "split", "context", "clips"]].itertuples(index=False)})
    scales = sorted({f"{v:g}" for v in frame["noise_scale"].dropna()})
    return "; ".join(parts) + (f"; motion noise sigma = {', '.join(scales)}" if scales else "")


def _cells(part: pd.DataFrame, prefix: str) -> str:
    values = part.set_index("metric")["increase_pct"]
    return " / ".join(f"{values.get(f'{prefix}_{c}', math.nan):+.1f}" for c in COMPONENTS)


def _grid(frame: pd.DataFrame, prefix: str) -> tuple[list[str], list[list[str]]]:
    """Header (model, perturbation, one column per occupancy) and rows of "exp / jaw / pose" cells."""
    levels = sorted(set(frame["occupancy"]))
    header = ["model", "perturbation"] + [f"{level:g}" for level in levels]
    body = []
    for (model, family), part in frame.groupby(["model", "perturbation"], sort=True):
        cells = {level: _cells(rows, prefix) for level, rows in part.groupby("occupancy")}
        body.append([model, family] + [cells.get(level, "") for level in levels])
    return header, body


def markdown(frame: pd.DataFrame) -> str:
    lines = ["# Robustness: increase over the clean run (%)", "",
             f"{caption(frame)}. Each cell: relative increase (perturbed - clean) / clean in % of exp / jaw / "
             "pose, per burst occupancy (bursts of 1 s; occupancy 1: the agent's speech silenced throughout, "
             "4-s bursts). Regenerate: "
             "`dyadbench robustness --table-only --results results-robustness --out leaderboards/`.",
             ""]
    for title, prefix in METRICS:
        header, body = _grid(frame, prefix)
        lines += [f"## {title}", "", "| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
        lines += ["| " + " | ".join(row) + " |" for row in body]
        lines.append("")
    return "\n".join(lines)


def latex(frame: pd.DataFrame) -> str:
    lines = [f"% Robustness: relative increase over the clean run (%), exp / jaw / pose; {caption(frame)}",
             "% Regenerate: dyadbench robustness --table-only --results results-robustness --out leaderboards/"]
    for title, prefix in METRICS:
        header, body = _grid(frame, prefix)
        lines += [rf"% {title}", r"\begin{tabular}{ll" + "r" * (len(header) - 2) + "}", r"\toprule",
                  " & ".join(latex_escape(h) for h in header) + r" \\", r"\midrule"]
        lines += [" & ".join(latex_escape(c) for c in row) + r" \\" for row in body]
        lines += [r"\bottomrule", r"\end{tabular}"]
    return "\n".join(lines) + "\n"


def table_texts(frame: pd.DataFrame) -> dict[str, str]:
    """``robustness.csv`` (every number), ``robustness.md`` and ``robustness.tex``."""
    buf = io.StringIO()
    frame.to_csv(buf, index=False, float_format="%.10g")
    return {f"{TABLE_STEM}.csv": buf.getvalue(), f"{TABLE_STEM}.md": markdown(frame),
            f"{TABLE_STEM}.tex": latex(frame)}
