"""Leaderboards built only from result files (and transcribed published rows).

- :func:`long_table`: one row per source / model / dataset / split / protocol / context / metric, with
  raw and publication-scaled values, the scale factor, ``higher_is_better``, the oracle flag, ``flags``
  (``train-overlap=N``: the model was fitted on a train split holding N evaluated clips, run with
  --allow-train-overlap; :meth:`dyadbench.results.EvalResult.flags`) and where the number comes from
  (``source = dyadbench`` with its result file, or ``source = paper`` with the table it was transcribed
  from).
- :func:`wide_table`: the paper layout of one suite (the printed columns its module declares, in the
  paper's order, scaled as printed: :mod:`dyadbench.metrics.columns`), one row per model and setting,
  with ``rank_group`` (:func:`prediction_sets`: the set of predictions the row was scored on),
  ``rank`` by the suite's primary column in the direction it declares (e.g. DualTalk FD exp ascending,
  gaze SimScore descending) among non-oracle rows of the same source/dataset/split/protocol/context
  **and** prediction set, and ``items`` (predictions scored; empty for published rows). Rows scored on
  different predictions (e.g. 40 items of the first 20 clips beside 1066 items) are never ranked
  against each other. Oracle and flagged rows are kept, marked and never ranked; a suite without a
  declaration is not ranked. The ground truth's own values of a suite's reference keys (e.g. L2L
  ``var_gt_exp``, declared with ``reference="var_exp"``) form an unranked ``ground truth`` row of each
  setting and prediction set, under the columns they refer to.
- :func:`latex_table`: the wide table as a booktabs LaTeX ``tabular`` (best ranked value per setting and
  prediction set in bold, never in oracle, flagged or ground-truth rows; a setting with several
  prediction sets shows each under its own line; oracle rows marked †, flagged rows ‡).
- :func:`table_texts` / :func:`write_tables`: one build's tables, written as a set into a folder that
  afterwards holds exactly them (tables of suites no longer present are removed).

Scales and directions come from the suite's declaration, so a result written before a key's scale was
declared (e.g. gaze ``gt_fix_ratio``, recorded with scale 1) is shown with the declared scale.

Published rows are stored as printed (scaled) in a CSV with columns ``source, reference, model,
dataset, split, protocol, context`` and one column per metric key (e.g. ``leaderboards/paper_timar.csv``);
their raw values are the printed values divided by the scale.
"""

from __future__ import annotations

import csv
import io
import math
from pathlib import Path
from typing import Iterable

import numpy as np
import pandas as pd

from dyadbench import atomic
from dyadbench import leaderboard_uncertainty as spread
from dyadbench.errors import InputError
from dyadbench.metrics.columns import ColumnSpec, SuiteColumns, declared
from dyadbench.motion import LAYOUTS
from dyadbench.protocol.config import variant_label
from dyadbench.registry import dataset_label, dataset_order
from dyadbench.results import results_frame

SETTING = ["source", "dataset", "split", "protocol", "context"]
LONG_COLUMNS = ["source", "model", "oracle", "flags", "dataset", "split", "protocol", "context", "suite",
                "metric", "component", "raw", "scaled", "scale", "higher_is_better", "items", "clips", "digest",
                "seed", "tail", "history_agent", "turn_seconds", "cfg_scale", "speech_norm", "weights_digest",
                "reference"]
_VARIANT_KEYS = ["turn_seconds", "tail", "history_agent", "cfg_scale", "seed", "speech_norm"]
_COMPONENTS = {c for layout in LAYOUTS.values() for c in layout.components}


PUBLISHED = "published"


def prediction_set(items: object, clips: object, digest: object = None) -> str:
    """The label of the set of predictions a row was scored on: ``"1066 items / 533 clips"``, with
    ``", data <first 12 hex digits>"`` (or ``", data unrecorded"``) when ``digest`` is given: see
    :func:`prediction_sets`; ``"published"`` for transcribed rows (no items recorded)."""
    if pd.isna(items):
        return PUBLISHED
    label = f"{int(items)} items / {int(clips)} clips" if pd.notna(clips) else f"{int(items)} items"
    if digest is None:
        return label
    return label + f", data {str(digest)[:12] if _recorded(digest) else 'unrecorded'}"


def _recorded(digest: object) -> bool:
    return isinstance(digest, str) and bool(digest)


def prediction_sets(part: pd.DataFrame) -> list[str]:
    """:func:`prediction_set` of every row of a long table. Rows of one setting with the same items and
    clips are one set, unless they record different data digests (the evaluated clips' content,
    :mod:`dyadbench.provenance`): then each recorded digest is its own set, and rows recording none form
    one more (``data unrecorded``). A row that records no digest is thus ranked with rows that do as long
    as nothing recorded contradicts it; ``dyadbench leaderboard`` warns about rows whose provenance no
    longer matches the current data (:mod:`dyadbench.staleness`)."""
    key = [part[c].astype(str) for c in SETTING + ["items", "clips"]]
    digests = part["digest"].where(part["digest"].map(_recorded))
    split = digests.groupby(key, dropna=False).transform("nunique") > 1
    return [prediction_set(items, clips, digest if several else None)
            for items, clips, digest, several in zip(part["items"], part["clips"], part["digest"], split)]


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
    spec = declared(suite)
    metrics = [c for c in header if c not in needed]
    unknown = [m for m in metrics if spec is None or spec.spec(m) is None]
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
                         "metric": metric, "component": _component(metric), "raw": value / spec.scale(metric),
                         "scaled": value, "scale": spec.scale(metric),
                         "higher_is_better": spec.higher_is_better(metric),
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
    _apply_declarations(frame)
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


def _apply_declarations(frame: pd.DataFrame) -> None:
    """In place: ``higher_is_better`` of every row, and ``scale`` / ``scaled`` = raw × scale of every declared
    key from its suite's declaration (undeclared keys keep the scale their result recorded)."""
    specs = [_spec(s, m) for s, m in zip(frame["suite"], frame["metric"])]
    known = np.array([c is not None for c in specs], dtype=bool)
    scale = np.array([c.scale if c is not None else math.nan for c in specs], dtype=np.float64)
    frame["higher_is_better"] = pd.Series([None if c is None else c.higher_is_better for c in specs],
                                          index=frame.index, dtype=object)
    frame.loc[known, "scale"] = scale[known]
    frame.loc[known, "scaled"] = frame.loc[known, "raw"].to_numpy(np.float64) * scale[known]


def _spec(suite: str, metric: str) -> ColumnSpec | None:
    columns = declared(suite)
    return None if columns is None else columns.spec(metric)


def _reject_duplicates(frame: pd.DataFrame) -> None:
    key = ["model", "flags", "dataset", "split", "protocol", "context", "turn_seconds", "tail", "history_agent",
           "cfg_scale", "speech_norm", "seed", "metric"]
    dup = frame[frame.duplicated(key, keep=False)]
    if not dup.empty:
        files = sorted(set(dup["file"]))
        raise InputError(files[0], f"the same run appears in several result files: {', '.join(files)}")


#: Rows are ranked only among rows of the same setting and prediction set (:func:`prediction_set`).
RANK_GROUP = SETTING + ["rank_group"]


def table_columns(suite: str, metrics: Iterable[str] = ()) -> list[str]:
    """The keys a suite's paper-layout tables print, in order: its declared printed columns; for a suite
    without a declaration, ``metrics`` in their order."""
    columns = declared(suite)
    return list(dict.fromkeys(metrics)) if columns is None else [c.key for c in columns.table_columns()]


def wide_table(long: pd.DataFrame, suite: str = "dualtalk", uncertainty: str = "none") -> pd.DataFrame:
    """The paper-layout table of one suite from the long table (scaled values; see module docstring).

    Rank = ``rank(method="min")`` of the primary column within a :data:`RANK_GROUP`, ascending when lower
    is better; rows without a value there are unranked. Rows are sorted by setting, then prediction set
    (most items first; published rows apart), oracle last, rank, model.
    """
    part = long[long["suite"] == suite]
    columns = table_columns(suite, part["metric"])
    index = SETTING + ["model", "oracle", "flags", "rank_group"]
    head = index + ["rank", "items"]
    if part.empty:
        return pd.DataFrame(columns=head + columns)
    part = part.assign(context=part["context"].astype("Int64").astype(str).fillna("").replace("<NA>", ""),
                       model=variant_models(part), flags=part["flags"].fillna(""),
                       rank_group=prediction_sets(part))
    wide = part.pivot_table(index=index, columns="metric", values="scaled", aggfunc="first").reset_index()
    for f in spread.MODES[uncertainty]:  # <col>_se or <col>_ci_low/_ci_high (dyadbench.leaderboard_uncertainty)
        extra = part.pivot_table(index=index, columns="metric", values=f, aggfunc="first")
        wide = wide.merge(extra.add_suffix(f"_{f}").reset_index(), on=index, how="left")
    shown = [c for key in columns for c in (key, *spread.columns(key, uncertainty))]
    items = part.groupby(index, dropna=False)["items"].first().astype("Int64").reset_index()
    wide = wide.merge(items, on=index, how="left").reindex(columns=index + ["items"] + shown)
    wide = pd.concat([wide, _reference_rows(part, declared(suite))], ignore_index=True)
    wide["rank"] = _ranks(wide, declared(suite))
    wide = wide.assign(_dataset=wide["dataset"].map(dataset_order), _largest=-wide["items"].astype("float64"),
                       _reference=wide["flags"] == REFERENCE).sort_values(
        ["source", "_dataset", *SETTING[2:], "_largest", "rank_group", "oracle", "_reference", "rank", "model"],
        kind="stable", na_position="last")
    return wide[head + shown].reset_index(drop=True)


#: The ``model`` and ``flags`` of a wide table's ground-truth row.
REFERENCE_MODEL = "ground truth"
REFERENCE = "reference"


def _reference_rows(part: pd.DataFrame, columns: SuiteColumns | None) -> pd.DataFrame:
    """One ground-truth row per setting and prediction set: the ground truth's own values of the suite's
    reference keys (e.g. ``var_gt_exp``) under the columns they refer to (``var_exp``); flagged
    :data:`REFERENCE`, so never ranked or bolded. Empty when the suite declares no reference keys."""
    references = {} if columns is None else columns.references()
    rows = part[part["metric"].isin(references)]
    if rows.empty:
        return pd.DataFrame()
    keys = SETTING + ["rank_group"]
    values = rows.assign(metric=rows["metric"].map(references)).pivot_table(
        index=keys, columns="metric", values="scaled", aggfunc="first")
    items = rows.groupby(keys)["items"].first().astype("Int64")
    return values.assign(items=items).reset_index().assign(model=REFERENCE_MODEL, oracle=False, flags=REFERENCE)


def _ranks(wide: pd.DataFrame, columns: SuiteColumns | None) -> pd.Series:
    """Rank of every row by the primary column among the ranked rows of its :data:`RANK_GROUP`."""
    rank = pd.Series(pd.array([pd.NA] * len(wide), dtype="Int64"), index=wide.index)
    ranked = ~unranked(wide)
    if columns is None or columns.primary not in wide or not ranked.any():
        return rank
    ascending = not columns.higher_is_better(columns.primary)
    values = wide.loc[ranked].groupby(RANK_GROUP)[columns.primary].rank(method="min", ascending=ascending)
    rank.loc[ranked] = values.astype("Int64")
    return rank


def unranked(rows: pd.DataFrame) -> pd.Series:
    """True for rows that are never ranked: oracle runs and flagged runs (e.g. train overlap)."""
    return rows["oracle"].astype(bool) | (rows["flags"].fillna("") != "")


def variant_models(part: pd.DataFrame) -> pd.Series:
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
    """A LaTeX tabular of a wide table: one block per setting, best ranked value per column, setting and
    prediction set in bold; a setting with several prediction sets heads each with its label."""
    specs = declared(suite)
    columns = table_columns(suite, [c for c in wide.columns if c not in SETTING + WIDE_TEXT])
    header = " & ".join(["Model"] + [latex_header(c, specs) for c in columns])
    lines = [r"\begin{tabular}{l" + "r" * len(columns) + "}", r"\toprule", header + r" \\", r"\midrule"]
    several = False
    for setting, block in wide.groupby(SETTING, sort=False):
        source, dataset, split, protocol, context = setting
        label = f"{dataset_label(dataset)} {split}, {protocol}" + (f", $n={context}$" if str(context) else "") + f" ({source})"
        lines.append(rf"\multicolumn{{{len(columns) + 1}}}{{l}}{{\emph{{{latex_escape(label)}}}}} \\")
        sets = list(dict.fromkeys(block["rank_group"]))
        several = several or len(sets) > 1
        for rank_group in sets:
            group = block[block["rank_group"] == rank_group]
            if len(sets) > 1:
                lines.append(rf"\multicolumn{{{len(columns) + 1}}}{{l}}{{\quad ranked among: "
                             rf"{latex_escape(rank_group)}}} \\")
            lines += _latex_rows(group, columns, specs, digits)
        lines.append(r"\midrule")
    lines[-1] = r"\bottomrule"
    lines += [r"\end{tabular}", r"% booktabs rules: \usepackage{booktabs}"]
    if several:
        lines.append(r"% Rows are ranked, and best values bolded, only among rows scored on the same predictions "
                     r"(same items and clips, no conflicting data digest): each such set is headed ``ranked among''.")
    if wide["oracle"].astype(bool).any():
        lines.append(r"% $^\dagger$ oracle: copies the ground truth; a pipeline check, never ranked.")
    if ((wide["flags"] != "") & (wide["flags"] != REFERENCE)).any():
        lines.append(r"% $^\ddagger$ flagged (e.g. the train split held evaluated clips); never ranked.")
    if (wide["flags"] == REFERENCE).any():
        lines.append(r"% \emph{ground truth}: the ground truth's own values of the columns judged by their closeness "
                     r"to it; never ranked.")
    return "\n".join(lines) + "\n"


#: The wide table's text columns besides :data:`SETTING`.
WIDE_TEXT = ["model", "oracle", "flags", "rank_group", "rank", "items"]


def _latex_rows(group: pd.DataFrame, columns: list[str], specs: SuiteColumns | None, digits: int) -> list[str]:
    """The rows of one prediction set; the best value of each ordered column among its ranked rows in bold
    (when there are at least two)."""
    best = {}
    ranked = group[~unranked(group)]
    for c in columns if len(ranked) > 1 else []:
        values = ranked[c].astype(float)
        higher = None if specs is None else specs.higher_is_better(c)
        if higher is not None and values.notna().any():
            best[c] = values.max() if higher else values.min()
    lines = []
    for _, row in group.iterrows():
        if row["flags"] == REFERENCE:
            name = rf"\emph{{{latex_escape(str(row['model']))}}}"
        else:
            name = latex_escape(str(row["model"])) + (r"$^\dagger$" if row["oracle"] else "") + (
                r"$^\ddagger$" if row["flags"] else "")
        cells = [name]
        for c in columns:
            v = float(row[c]) if pd.notna(row[c]) else math.nan
            text = "--" if math.isnan(v) else f"{v:.{digits}f}".removeprefix("-" if round(v, digits) == 0 else "")
            if c in best and row.name in ranked.index and not math.isnan(v) and np.isclose(v, best[c]):
                text = rf"\textbf{{{text}}}"
            cells.append(text + spread.latex_suffix(row, c, digits))
        lines.append(" & ".join(cells) + r" \\")
    return lines


def latex_header(key: str, specs: SuiteColumns | None) -> str:
    r"""The declared header with its direction arrow and scale (e.g. ``FD jaw$\downarrow$ $\times10^{3}$``,
    ``saccade (\%)``); an undeclared key as it is."""
    spec = None if specs is None else specs.spec(key)
    if spec is None:
        return latex_escape(key)
    arrow = {True: r"$\uparrow$", False: r"$\downarrow$", None: ""}[spec.higher_is_better]
    if spec.unit is not None:
        factor = f" ({latex_escape(spec.unit)})"
    else:
        factor = "" if spec.scale == 1.0 else rf" $\times10^{{{int(round(math.log10(spec.scale)))}}}$"
    return f"{latex_escape(spec.header)}{arrow}{factor}"


def latex_escape(text: str) -> str:
    """``text`` for a LaTeX text cell: backslash, ``&``, ``%``, ``_`` and ``#`` escaped."""
    for a, b in (("\\", r"\textbackslash{}"), ("&", r"\&"), ("%", r"\%"), ("_", r"\_"), ("#", r"\#")):
        text = text.replace(a, b)
    return text


def table_texts(long: pd.DataFrame, latex: bool = False, uncertainty: str = "none") -> dict[str, str]:
    """Every table of one build by file name: ``long.csv``, ``<suite>_wide.csv`` per suite and, with
    ``latex``, ``<suite>_wide.tex``. Built whole in memory, so a failure writes nothing. ``uncertainty``
    ``se`` or ``ci`` adds the results' recorded uncertainty to the wide tables
    (:mod:`dyadbench.leaderboard_uncertainty`)."""
    tables = {"long.csv": _csv(long)}
    measured = long if uncertainty == "none" else spread.with_uncertainty(long)
    for suite in sorted(set(long["suite"])):
        wide = wide_table(measured, suite, uncertainty)
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
