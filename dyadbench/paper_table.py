"""TIMAR's Table 1 laid out from the leaderboard's long table: rows per context, and the relative change
of TIMAR against DualTalk per column, as the paper marks it.

One table per source (``dyadbench``: result files; ``paper``: the transcribed published rows) and
dataset, with a block per split (test, ood) and in each the context rows ``offline`` (DualTalk only, the
published DualTalk protocol: dyadbench ``dualtalk-offline``; paper DualTalk-official and
DualTalk-retrained from its Table 2) and streaming n = 0, 3, 7. At each streaming context the
reference rows come first (dyadbench ``dualtalk``; paper DualTalk-official, DualTalk-retrained), then
each compared row (``timar``, ``timar-stream``; paper TIMAR), each followed by its change against the
first reference row of the same split and context, for every printed column of the DualTalk suite
(publication scaling, :mod:`dyadbench.metrics.columns`)::

    change (%) = 100 × (compared − reference) / |reference|

A change is *better* when it goes the column's declared way (FD, P-FD, MSE and rPCC lower; SID higher)
and *worse* otherwise; it is undefined when a value is missing or the reference is 0.

Only runs at the default protocol settings enter (no variant label,
:func:`dyadbench.protocol.config.variant_label`, so e.g. ``timar@cfg1.5`` stays out), whichever their
speech normalisation (the published numbers used the whole clip's; such rows are marked). A row without a
result is shown as missing and listed, never filled in. Marks: ‡ flagged (train overlap,
:meth:`dyadbench.results.EvalResult.flags`), § not strictly causal (the result records
``speech_norm = "clip"``: waveform statistics of the whole clip; results that record no setting used
the per-window normalisation).

:func:`table1_frame` builds the rows; :func:`table1_texts` renders ``table1_<source>_<dataset>`` as
``.csv`` (``kind`` = value | change_pct | better: 1 better, 0 worse, empty when equal or undefined),
``.md`` and ``.tex``.
"""

from __future__ import annotations

import inspect
import io
import math
from dataclasses import dataclass

import pandas as pd

from dyadbench.errors import InputError
from dyadbench.leaderboard import latex_escape, latex_header, table_columns
from dyadbench.metrics.columns import declared
from dyadbench.protocol.config import variant_label
from dyadbench.results import load_result

SUITE = "dualtalk"
SPLITS = ("test", "ood")
OFFLINE = "offline"
CONTEXTS = (OFFLINE, "0", "3", "7")
#: The protocol settings that name a variant run (the keyword arguments of ``variant_label``), less the
#: speech normalisation: a whole-clip run is the published protocol, shown with the mark § instead.
VARIANT_SETTINGS = tuple(p for p in inspect.signature(variant_label).parameters if p != "speech_norm")
KEY = ["source", "dataset", "split", "context", "model"]
TEXT_COLUMNS = KEY + ["kind", "versus", "marks", "file"]
FLAGGED, NONCAUSAL = "‡", "§"


@dataclass(frozen=True)
class Layout:
    """The rows of one source's Table 1: ``offline`` (DualTalk over the whole clip) at the offline context;
    ``references`` (DualTalk; changes are measured against the first), then ``compared`` (TIMAR) at each
    streaming context."""

    offline: tuple[str, ...]
    references: tuple[str, ...]
    compared: tuple[str, ...]

    def rows(self, context: str) -> tuple[str, ...]:
        """The models shown at ``context``, in order."""
        return self.offline if context == OFFLINE else self.references + self.compared


LAYOUTS = {"dyadbench": Layout(("dualtalk-offline",), ("dualtalk",), ("timar", "timar-stream")),
           "paper": Layout(("DualTalk-official", "DualTalk-retrained"), ("DualTalk-official", "DualTalk-retrained"),
                           ("TIMAR",))}


def table1_runs(long: pd.DataFrame) -> pd.DataFrame:
    """One row per Table 1 run of the long table (a layout's model, split and context, default settings):
    :data:`KEY`, ``marks``, ``file`` and the printed columns (scaled). InputError naming the files when
    two runs fill the same row."""
    context = long["context"].astype("Int64").astype(str).where(long["protocol"] != OFFLINE, OFFLINE)
    layouts = [LAYOUTS.get(s) for s in long["source"]]
    keep = pd.Series([lay is not None and m in lay.rows(c) for lay, m, c in zip(layouts, long["model"], context)],
                     index=long.index, dtype=bool)
    part = long.assign(context=context, flags=long["flags"].fillna(""), file=long["reference"])
    shown = (part["suite"] == SUITE) & part["split"].isin(SPLITS) & part["context"].isin(CONTEXTS) & keep
    part = part[shown & _default_settings(part)]
    if part.empty:
        return pd.DataFrame(columns=KEY + ["marks", "file"] + table_columns(SUITE))
    wide = part.set_index(KEY + ["flags", "file", "metric"])["scaled"].unstack("metric").reset_index()
    repeated = wide[wide.duplicated(KEY, keep=False)]
    if not repeated.empty:
        files = sorted(set(repeated["file"]))
        raise InputError(files[0], "several runs fill one row of Table 1 (same model, split and context at the "
                                   f"default settings): {', '.join(files)}; pass only the ones to show")
    marks = [_marks(flags, file if source == "dyadbench" else None)
             for flags, file, source in zip(wide["flags"], wide["file"], wide["source"])]
    return wide.assign(marks=marks).reindex(columns=KEY + ["marks", "file"] + table_columns(SUITE))


def _default_settings(long: pd.DataFrame) -> pd.Series:
    """True for rows run at the default protocol settings (published rows record none)."""
    settings = long[list(VARIANT_SETTINGS)].astype(object)
    return pd.Series([variant_label(**{k: v for k, v in zip(VARIANT_SETTINGS, row) if pd.notna(v)}) == ""
                      for row in settings.itertuples(index=False)], index=long.index, dtype=bool)


def _marks(flags: str, file: str | None) -> str:
    """``flags`` and, for a result file recording whole-clip speech normalisation, ``speech_norm=clip``."""
    marks = [flags] if flags else []
    if file is not None and speech_norm(file) == "clip":
        marks.append("speech_norm=clip")
    return "; ".join(marks)


def speech_norm(file: str) -> str:
    """The speech normalisation a result records; ``window`` when it records none (written before the
    setting existed, when only the per-window one did)."""
    return getattr(load_result(file).protocol, "speech_norm", "window")


def table1_frame(long: pd.DataFrame) -> tuple[pd.DataFrame, list[str]]:
    """Every Table 1 (see the module docstring) as one frame of :data:`TEXT_COLUMNS` and the printed
    columns, and the rows that have no run (``source dataset split context model``)."""
    runs = table1_runs(long)
    columns = table_columns(SUITE)
    found = {tuple(r[k] for k in KEY): r for _, r in runs.iterrows()}
    rows, missing = [], []
    for source, dataset in sorted(set(zip(runs["source"], runs["dataset"]))):
        layout = LAYOUTS[source]
        for split in SPLITS:
            for context in CONTEXTS:
                where = {"source": source, "dataset": dataset, "split": split, "context": context}
                reference = found.get((source, dataset, split, context, layout.references[0]))
                for model in layout.rows(context):
                    run = found.get((source, dataset, split, context, model))
                    if run is None:
                        missing.append(f"{source} {dataset} {split} {context} {model}")
                    rows.append({**where, "model": model, "kind": "value", "versus": "",
                                 "marks": "missing" if run is None else run["marks"],
                                 "file": "" if run is None else run["file"],
                                 **{c: math.nan if run is None else run[c] for c in columns}})
                    if model in layout.compared:
                        rows += _change_rows({**where, "model": model, "versus": layout.references[0]},
                                             run, reference, columns)
    frame = pd.DataFrame(rows, columns=TEXT_COLUMNS + columns)
    return frame, missing


def _change_rows(head: dict, run: pd.Series | None, reference: pd.Series | None, columns: list[str]) -> list[dict]:
    """The ``change_pct`` and ``better`` rows of ``run`` against ``reference`` (see module docstring)."""
    spec = declared(SUITE)
    change, better = {}, {}
    for c in columns:
        value = math.nan if run is None or reference is None else relative_change(run[c], reference[c])
        change[c] = value
        better[c] = verdict(value, spec.higher_is_better(c))
    return [{**head, "kind": "change_pct", "marks": "", "file": "", **change},
            {**head, "kind": "better", "marks": "", "file": "", **better}]


def relative_change(value: float, reference: float) -> float:
    """``100 × (value − reference) / |reference|``; NaN when either is missing or the reference is 0."""
    if pd.isna(value) or pd.isna(reference) or reference == 0:
        return math.nan
    return 100.0 * (value - reference) / abs(reference)


def verdict(change: float, higher_is_better: bool | None) -> float:
    """1.0 when ``change`` goes the column's way, 0.0 when it goes against it, NaN when it is 0, undefined
    or the column has no direction."""
    if math.isnan(change) or change == 0 or higher_is_better is None:
        return math.nan
    return 1.0 if (change > 0) == higher_is_better else 0.0


def table1_texts(long: pd.DataFrame) -> tuple[dict[str, str], list[str]]:
    """The files of every Table 1 by name (``table1_<source>_<dataset>.csv``, ``.md``, ``.tex``) and the
    missing rows (:func:`table1_frame`). The same long table gives the same bytes."""
    frame, missing = table1_frame(long)
    texts = {}
    for (source, dataset), table in frame.groupby(["source", "dataset"], sort=True):
        stem = f"table1_{source}_{dataset}"
        buf = io.StringIO()
        table.to_csv(buf, index=False, float_format="%.10g")
        texts[f"{stem}.csv"] = buf.getvalue()
        texts[f"{stem}.md"] = markdown_table(table)
        texts[f"{stem}.tex"] = latex_table1(table)
    return texts, missing


def _display_rows(table: pd.DataFrame):
    """(split, context shown or '', model label, row) of a table's value and change rows; ``better``
    rows are read beside their change rows."""
    better = table[table["kind"] == "better"].set_index(KEY)
    previous = None
    for _, row in table[table["kind"] != "better"].iterrows():
        group = (row["split"], row["context"])
        context = "" if group == previous else ("offline" if row["context"] == OFFLINE else f"n = {row['context']}")
        previous = group
        judged = better.loc[tuple(row[k] for k in KEY)] if row["kind"] == "change_pct" else None
        yield row["split"], context, row, judged


def _mark_symbols(marks: str) -> str:
    symbols = ""
    if "train-overlap" in marks:
        symbols += FLAGGED
    if "speech_norm=clip" in marks:
        symbols += NONCAUSAL
    return symbols


def _notes(table: pd.DataFrame, percent: str, marking: str) -> list[str]:
    """The legend lines of a table (how changes are marked, the marks it uses, missing rows) and its
    source files."""
    versus = ", ".join(sorted(set(table.loc[table["kind"] == "change_pct", "versus"])))
    notes = [f"Δ: the row above against {versus} at the same split and context, 100 × (row − {versus}) / "
             f"|{versus}| in {percent}; {marking} by the column's direction (↓ lower is better, ↑ higher is "
             "better)."]
    marks = " ".join(table["marks"])
    if "missing" in marks:
        notes.append("—: no result at the default protocol settings (missing row), or a change that is undefined.")
    if "train-overlap" in marks:
        notes.append(f"{FLAGGED} flagged: the model's train split held evaluated clips.")
    if "speech_norm=clip" in marks:
        notes.append(f"{NONCAUSAL} not strictly causal: speech normalised with whole-clip statistics.")
    files = sorted(set(table["file"]) - {""})
    notes.append("Source: " + ", ".join(files) + ".")
    return notes


def markdown_table(table: pd.DataFrame) -> str:
    """One source's and dataset's Table 1 as Markdown: a table per split; values with 2 decimals,
    changes in % with 1 decimal and ✓ (better) or ✗ (worse)."""
    spec = declared(SUITE)
    columns = [c for c in table.columns if c not in TEXT_COLUMNS]
    arrows = {True: " ↑", False: " ↓", None: ""}
    header = ["context", "model"] + [spec.spec(c).text_header + arrows[spec.higher_is_better(c)] for c in columns]
    first = table.iloc[0]
    lines = [f"# TIMAR Table 1 layout: {first['source']}, {first['dataset']}", "",
             "Generated by `dyadbench leaderboard --table1` (`dyadbench.paper_table`) from the files named below; "
             "do not edit by hand.", ""]
    split = None
    for row_split, context, row, judged in _display_rows(table):
        if row_split != split:
            split = row_split
            lines += ([""] if lines[-1] else []) + [f"## {split}", "", "| " + " | ".join(header) + " |",
                                                     "|---" * len(header) + "|"]
        if judged is None:
            label = row["model"] + _mark_symbols(row["marks"]) + (" (missing)" if row["marks"] == "missing" else "")
            cells = ["—" if pd.isna(row[c]) else f"{row[c]:.2f}" for c in columns]
        else:
            label = f"Δ vs {row['versus']}"
            cells = [_markdown_change(row[c], judged[c]) for c in columns]
        lines.append("| " + " | ".join([context, label] + cells) + " |")
    lines += [""] + [line for note in _notes(table, "%", "✓ better, ✗ worse") for line in (note, "")]
    return "\n".join(lines).rstrip("\n") + "\n"


def _markdown_change(change: float, better: float) -> str:
    if pd.isna(change):
        return "—"
    return f"{change:+.1f}%" + ("" if pd.isna(better) else " ✓" if better else " ✗")


def latex_table1(table: pd.DataFrame) -> str:
    r"""One source's and dataset's Table 1 as a LaTeX ``tabular``: a block per split, values with 2
    decimals, changes in % with 1 decimal, bold where better; the legend as ``%`` comments."""
    spec = declared(SUITE)
    columns = [c for c in table.columns if c not in TEXT_COLUMNS]
    width = len(columns) + 2
    lines = [r"\begin{tabular}{ll" + "r" * len(columns) + "}", r"\toprule",
             " & ".join(["Context", "Model"] + [latex_header(c, spec) for c in columns]) + r" \\"]
    split = None
    for row_split, context, row, judged in _display_rows(table):
        if row_split != split:
            split = row_split
            heading = latex_escape(f"{row['dataset']} {split} ({row['source']})")
            lines += [r"\midrule", rf"\multicolumn{{{width}}}{{l}}{{\emph{{{heading}}}}} \\"]
        if judged is None:
            symbols = _mark_symbols(row["marks"]).replace(FLAGGED, r"$^\ddagger$").replace(NONCAUSAL, r"$^\S$")
            label = latex_escape(row["model"]) + symbols
            cells = ["--" if pd.isna(row[c]) else f"{row[c]:.2f}" for c in columns]
        else:
            label = rf"\quad $\Delta$ vs {latex_escape(row['versus'])}"
            cells = [_latex_change(row[c], judged[c]) for c in columns]
        lines.append(" & ".join([latex_escape(context), label] + cells) + r" \\")
    lines += [r"\bottomrule", r"\end{tabular}"]
    lines += ["% " + latex_escape(note).replace("—", "--") for note in _notes(table, "percent", "bold where better")]
    return "\n".join(lines) + "\n"


def _latex_change(change: float, better: float) -> str:
    if pd.isna(change):
        return "--"
    text = f"${change:+.1f}$\\%"
    return rf"\textbf{{{text}}}" if better == 1 else text
