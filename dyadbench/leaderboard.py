"""Leaderboards built only from result files (and transcribed published rows).

- :func:`long_table`: one row per source / model / dataset / split / protocol / context / metric, with
  raw and publication-scaled values, the scale factor, ``higher_is_better``, the oracle flag, ``flags``
  (``train-overlap=N``: the model was fitted on a train split holding N evaluated clips, run with
  --allow-train-overlap; :meth:`dyadbench.results.EvalResult.flags`) and where the number comes from
  (``source = dyadbench`` with its result file, or ``source = paper`` with the table it was transcribed
  from).
- :func:`wide_table`: the paper layout of one suite (DualTalk/TIMAR: FD, P-FD, MSE, SID, rPCC for
  exp/jaw/pose, scaled as printed), one row per model and setting, with ``rank`` by the first column
  among non-oracle rows of the same source/dataset/split/protocol/context and ``items`` (predictions
  scored; empty for published rows). Oracle and flagged rows are kept, marked and never ranked.
- :func:`latex_table`: the wide table as a LaTeX ``tabular`` (best ranked value per group in bold; oracle
  rows marked †, flagged rows ‡).
- :func:`table_texts` / :func:`write_tables`: one build's tables, written as a set into a folder that
  afterwards holds exactly them (tables of suites no longer present are removed).

Published rows are stored as printed (scaled) in a CSV with columns ``source, reference, model,
dataset, split, protocol, context`` and one column per metric key (e.g. ``leaderboards/paper_timar.csv``);
their raw values are the printed values divided by the scale.
"""

from __future__ import annotations

import csv
import importlib
import io
import math
from pathlib import Path
from typing import Iterable

import numpy as np
import pandas as pd

from dyadbench import atomic
from dyadbench.errors import InputError
from dyadbench.motion import LAYOUTS
from dyadbench.protocol.config import variant_label
from dyadbench.results import results_frame

SETTING = ["source", "dataset", "split", "protocol", "context"]
LONG_COLUMNS = ["source", "model", "oracle", "flags", "dataset", "split", "protocol", "context", "suite",
                "metric", "component", "raw", "scaled", "scale", "higher_is_better", "items", "seed", "tail",
                "history_agent", "turn_seconds", "cfg_scale", "weights_digest", "reference"]
_VARIANT_KEYS = ["turn_seconds", "tail", "history_agent", "cfg_scale", "seed"]
_COMPONENTS = {c for layout in LAYOUTS.values() for c in layout.components}


def suite_info(suite: str) -> tuple[list[str], dict[str, float], dict[str, bool | None]]:
    """(paper columns in order, scale per key, higher_is_better per key) of a suite; empty if unknown."""
    if suite == "dualtalk":
        m = importlib.import_module("dyadbench.metrics.dualtalk")
        keys = [k for name in m.PAPER_ORDER if m.METRIC_INFO[name].in_paper for k in m.METRIC_INFO[name].keys()]
        return keys, dict(m.SCALE), dict(m.HIGHER_IS_BETTER)
    if suite == "l2l":
        m = importlib.import_module("dyadbench.metrics.l2l")
        keys = m.keys(m.L2LParams())
        better = {k: m.HIGHER_IS_BETTER[k.rsplit("_", 1)[0]] for k in keys}
        return keys, {k: 1.0 for k in keys}, better
    return [], {}, {}


def _component(metric: str) -> str:
    tail = metric.rsplit("_", 1)[-1]
    return tail if tail in _COMPONENTS else ""


_PAPER_TEXT = ("source", "reference", "model", "dataset", "split", "protocol")


def paper_rows(path: str | Path, suite: str = "dualtalk") -> pd.DataFrame:
    """Long rows of a transcribed published table (see module docstring).

    An empty cell is a value the table does not print (NaN; for ``context``: no context). InputError
    naming the file, line and column for an empty file, missing, repeated or unknown columns, a ragged
    line, no rows, an empty text cell, a context that is not a whole number or a value that is not a
    finite number.
    """
    path = Path(path)
    header, lines = _read_csv(path)
    if not lines:
        raise InputError(path, "no published rows below the header")
    needed = set(_PAPER_TEXT) | {"context"}
    if not needed <= set(header):
        raise InputError(path, f"missing columns {', '.join(sorted(needed - set(header)))}")
    _, scale, better = suite_info(suite)
    metrics = [c for c in header if c not in needed]
    unknown = [m for m in metrics if m not in scale]
    if unknown:
        raise InputError(path, f"unknown {suite} metric columns: {', '.join(unknown)}")
    rows = []
    for line, cells in lines:
        r = dict(zip(header, cells))
        for column in _PAPER_TEXT:
            if not r[column].strip():
                raise InputError(path, f"line {line}, column {column!r}: empty")
        context = _cell_number(path, line, "context", r["context"], int)
        for metric in metrics:
            value = _cell_number(path, line, metric, r[metric], float)
            rows.append({"source": r["source"], "model": r["model"], "oracle": False, "dataset": r["dataset"],
                         "split": r["split"], "protocol": r["protocol"], "context": context, "suite": suite,
                         "metric": metric, "component": _component(metric), "raw": value / scale[metric],
                         "scaled": value, "scale": scale[metric], "higher_is_better": better.get(metric),
                         "reference": f"{r['reference']} ({path.name})"})
    return pd.DataFrame(rows)


def _read_csv(path: Path) -> tuple[list[str], list[tuple[int, list[str]]]]:
    """Header and (line number, cells) of a CSV file; InputError if unreadable, empty, with a repeated
    column or a line whose number of cells differs from the header's."""
    try:
        with path.open(newline="", encoding="utf-8") as f:
            reader = csv.reader(f)
            records = [(reader.line_num, cells) for cells in reader]
    except (OSError, UnicodeDecodeError, csv.Error) as exc:
        raise InputError(path, f"not a readable published-rows CSV ({exc})") from None
    records = [(n, cells) for n, cells in records if cells]  # blank lines
    if not records:
        raise InputError(path, "empty file (expected a header line and published rows)")
    (_, header), lines = records[0], records[1:]
    repeated = sorted({c for c in header if header.count(c) > 1})
    if repeated:
        raise InputError(path, f"repeated columns {', '.join(repeated)}")
    for n, cells in lines:
        if len(cells) != len(header):
            raise InputError(path, f"line {n} has {len(cells)} cells, the header has {len(header)}")
    return header, lines


def _cell_number(path: Path, line: int, column: str, text: str, kind: type) -> float | int | None:
    """A numeric cell: empty -> None (context) or NaN (metric); else a finite ``kind`` or InputError."""
    text = text.strip()
    if not text:
        return None if kind is int else math.nan
    try:
        value = kind(text)
    except ValueError:
        value = None
    if value is None or not math.isfinite(value):
        what = "a whole number" if kind is int else "a finite number"
        raise InputError(path, f"line {line}, column {column!r}: {text!r} is not {what}")
    return value


def long_table(result_paths: Iterable[str | Path], paper: Iterable[str | Path] = ()) -> pd.DataFrame:
    """The long leaderboard from result files/folders and published-rows CSVs."""
    frame = results_frame(result_paths)
    _reject_duplicates(frame)
    frame = frame.assign(source="dyadbench", reference=frame["file"], component=frame["metric"].map(_component))
    frame["higher_is_better"] = [suite_info(s)[2].get(m) for s, m in zip(frame["suite"], frame["metric"])]
    parts = [frame] + [paper_rows(p) for p in paper]
    parts = [p for p in parts if not p.empty]
    if not parts:
        return pd.DataFrame(columns=LONG_COLUMNS)
    out = pd.concat(parts, ignore_index=True).reindex(columns=LONG_COLUMNS)
    out["context"] = out["context"].astype("Int64")
    out["oracle"] = out["oracle"].astype(bool)
    out["flags"] = out["flags"].fillna("")
    return out.sort_values(["suite", "dataset", "split", "protocol", "context", "source", "oracle", "model",
                            "metric"], kind="stable").reset_index(drop=True)


def _reject_duplicates(frame: pd.DataFrame) -> None:
    key = ["model", "flags", "dataset", "split", "protocol", "context", "turn_seconds", "tail", "history_agent",
           "cfg_scale", "seed", "metric"]
    dup = frame[frame.duplicated(key, keep=False)]
    if not dup.empty:
        files = sorted(set(dup["file"]))
        raise InputError(files[0], f"the same run appears in several result files: {', '.join(files)}")


def wide_table(long: pd.DataFrame, suite: str = "dualtalk") -> pd.DataFrame:
    """The paper-layout table of one suite from the long table (scaled values; see module docstring)."""
    part = long[long["suite"] == suite]
    columns, _, better = suite_info(suite)
    if not columns:
        columns = list(dict.fromkeys(part["metric"]))
    index = SETTING + ["model", "oracle", "flags"]
    if part.empty:
        return pd.DataFrame(columns=index + ["rank", "items"] + columns)
    part = part.assign(context=part["context"].astype("Int64").astype(str).replace("<NA>", ""),
                       model=_variant_models(part), flags=part["flags"].fillna(""))
    wide = part.pivot_table(index=index, columns="metric", values="scaled", aggfunc="first").reset_index()
    items = part.groupby(index, dropna=False)["items"].first().astype("Int64").reset_index()
    wide = wide.merge(items, on=index, how="left").reindex(columns=index + ["items"] + columns)
    first = columns[0]
    ascending = not bool(better.get(first, False))
    wide["rank"] = pd.array([pd.NA] * len(wide), dtype="Int64")
    ranked = ~unranked(wide)
    wide.loc[ranked, "rank"] = (wide[ranked].groupby(SETTING)[first]
                                .rank(method="min", ascending=ascending).astype("Int64"))
    wide = wide.sort_values(SETTING + ["oracle", "rank", "model"], kind="stable", na_position="last")
    return wide[index + ["rank", "items"] + columns].reset_index(drop=True)


def unranked(rows: pd.DataFrame) -> pd.Series:
    """True for rows that are never ranked: oracle runs and flagged runs (e.g. train overlap)."""
    return rows["oracle"].astype(bool) | (rows["flags"].fillna("") != "")


def _variant_models(part: pd.DataFrame) -> pd.Series:
    """Model labels with the run's non-default protocol settings, e.g. ``timar (cfg2)``.

    Runs of one model that differ only in guidance scale, seed, tail, history policy or turn length
    then stay separate rows of the wide table instead of being merged. Published rows (no settings
    recorded) keep their names.
    """
    columns = ["model", *_VARIANT_KEYS]
    keys = part[columns].astype(object).where(part[columns].notna(), None)
    labels = {}
    for record in keys.drop_duplicates().itertuples(index=False):
        settings = {k: v for k, v in zip(_VARIANT_KEYS, record[1:]) if v is not None}
        if "seed" in settings:
            settings["seed"] = int(settings["seed"])
        variant = variant_label(**settings)
        labels[tuple(record)] = f"{record[0]} ({variant})" if variant else record[0]
    return pd.Series([labels[tuple(r)] for r in keys.itertuples(index=False)], index=part.index)


def latex_table(wide: pd.DataFrame, suite: str = "dualtalk", digits: int = 2) -> str:
    """A LaTeX tabular of a wide table; best ranked value per column and group in bold, oracle marked."""
    columns, scale, better = suite_info(suite)
    columns = columns or [c for c in wide.columns
                          if c not in SETTING + ["model", "oracle", "flags", "rank", "items"]]
    header = " & ".join(["Model"] + [_latex_header(c, scale.get(c, 1.0), better.get(c)) for c in columns])
    lines = [r"\begin{tabular}{l" + "r" * len(columns) + "}", r"\toprule", header + r" \\", r"\midrule"]
    for setting, group in wide.groupby(SETTING, sort=False):
        source, dataset, split, protocol, context = setting
        label = f"{dataset} {split}, {protocol}" + (f", $n={context}$" if str(context) else "") + f" ({source})"
        lines.append(rf"\multicolumn{{{len(columns) + 1}}}{{l}}{{\emph{{{_escape(label)}}}}} \\")
        best = {}
        ranked = group[~unranked(group)]
        for c in columns:
            values = ranked[c].astype(float)
            if better.get(c) is not None and values.notna().any():
                best[c] = values.max() if better[c] else values.min()
        for _, row in group.iterrows():
            name = _escape(str(row["model"])) + (r"$^\dagger$" if row["oracle"] else "") + (
                r"$^\ddagger$" if row["flags"] else "")
            cells = [name]
            for c in columns:
                v = float(row[c]) if pd.notna(row[c]) else math.nan
                text = "--" if math.isnan(v) else f"{v:.{digits}f}"
                if c in best and row.name in ranked.index and not math.isnan(v) and np.isclose(v, best[c]):
                    text = rf"\textbf{{{text}}}"
                cells.append(text)
            lines.append(" & ".join(cells) + r" \\")
        lines.append(r"\midrule")
    lines[-1] = r"\bottomrule"
    lines.append(r"\end{tabular}")
    if wide["oracle"].astype(bool).any():
        lines.append(r"% $^\dagger$ oracle: copies the ground truth; a pipeline check, never ranked.")
    if (wide["flags"] != "").any():
        lines.append(r"% $^\ddagger$ flagged (e.g. the train split held evaluated clips); never ranked.")
    return "\n".join(lines) + "\n"


def _latex_header(key: str, scale: float, higher: bool | None) -> str:
    name, _, comp = key.rpartition("_")
    arrow = "" if higher is None else (r"$\uparrow$" if higher else r"$\downarrow$")
    factor = "" if scale == 1.0 else rf" $\times10^{{{int(round(math.log10(scale)))}}}$"
    return f"{_escape(name.upper().replace('PFD', 'P-FD').replace('RPCC', 'rPCC'))}{arrow} {comp}{factor}"


def _escape(text: str) -> str:
    for a, b in (("\\", r"\textbackslash{}"), ("&", r"\&"), ("%", r"\%"), ("_", r"\_"), ("#", r"\#")):
        text = text.replace(a, b)
    return text


def table_texts(long: pd.DataFrame, latex: bool = False) -> dict[str, str]:
    """Every table of one build by file name: ``long.csv``, ``<suite>_wide.csv`` per suite and, with
    ``latex``, ``<suite>_wide.tex``. Built whole in memory, so a failure writes nothing."""
    tables = {"long.csv": _csv(long)}
    for suite in sorted(set(long["suite"])):
        wide = wide_table(long, suite)
        tables[f"{suite}_wide.csv"] = _csv(wide)
        if latex:
            tables[f"{suite}_wide.tex"] = latex_table(wide, suite)
    return tables


#: The names of the tables a build writes; files of the output folder matching them belong to builds.
TABLE_NAMES = ("long.csv", "*_wide.csv", "*_wide.tex")


def write_tables(out: str | Path, tables: dict[str, str]) -> tuple[list[Path], list[Path]]:
    """Write one build's tables into ``out`` as a set and remove earlier builds' tables that are not in
    it (only files named like :data:`TABLE_NAMES`), so ``out`` holds exactly this build's tables.

    Returns (written, removed).
    """
    out = Path(out)
    written = atomic.write_texts({out / name: text for name, text in tables.items()})
    stale = sorted({p for pattern in TABLE_NAMES for p in out.glob(pattern) if p.is_file()} - set(written))
    for path in stale:
        path.unlink()
    return written, stale


def _csv(frame: pd.DataFrame) -> str:
    buf = io.StringIO()
    frame.to_csv(buf, index=False, float_format="%.10g")
    return buf.getvalue()
