"""The results page (``RESULTS.md``): every leaderboard and benchmark table, generated from committed files.

:func:`render_page` builds it from

- result files (``dyadbench eval`` / ``sweep``) and the published rows, through the leaderboard's own
  :func:`dyadbench.leaderboard.long_table` and :func:`~dyadbench.leaderboard.wide_table`: one table per
  suite and setting (source, dataset, split, protocol, context) with every column of the wide table,
  losses included, shown transposed (one row per column of the wide table, one column per model, in
  rank order) so that suites with many metrics stay readable;
- benchmark result files ``benchmarks/results/NAME.json`` written by ``benchmarks/output.py`` (command,
  seed, machine, Markdown), and Markdown files there without a JSON twin (written before the scripts
  recorded command and machine; included verbatim, as such).

Each table names the files it comes from and the command that regenerates them. The page holds no
timestamps and numbers are formatted with a fixed rule (:func:`cell`), files and groups are sorted, so
the same committed files give the same bytes.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Iterable

import pandas as pd

from dyadbench import strict_json
from dyadbench.errors import InputError
from dyadbench.leaderboard import SETTING, long_table, wide_table
from dyadbench.registry import dataset_label

#: Significant digits of every number on the page.
DIGITS = 4
_ROW_LABELS = ("rank", "items", "oracle", "flags")


def cell(value) -> str:
    """One table cell: numbers with :data:`DIGITS` significant digits (``%.4g``), missing as ``–``,
    booleans as ``yes``/empty, ``|`` escaped."""
    if value is None or value is pd.NA or (isinstance(value, float) and math.isnan(value)):
        return "–"
    if isinstance(value, bool):
        return "yes" if value else ""
    if isinstance(value, float):
        return f"{value:.{DIGITS}g}"
    return str(value).replace("|", "\\|")


def shown_path(path: str | Path) -> str:
    """``path`` relative to the working folder when inside it (so the page does not depend on where the
    repository lies), else as given."""
    absolute = Path(path).resolve()
    cwd = Path.cwd().resolve()
    return str(absolute.relative_to(cwd)) if absolute.is_relative_to(cwd) else str(path)


def leaderboard_sections(results: Iterable[Path], paper: Iterable[Path]) -> list[str]:
    """Markdown of every suite's wide table, one transposed table per setting."""
    long = long_table(results, paper)
    lines = ["## Leaderboards", "",
             "Every column of `dyadbench leaderboard`'s wide table (`leaderboards/<suite>_wide.csv`), losses "
             "included, scaled as published; ↑ higher is better, ↓ lower is better. Rows with a flag or marked "
             "oracle are never ranked.", ""]
    for suite in sorted(set(long["suite"])):
        part = long[long["suite"] == suite]
        better = dict(zip(part["metric"], part["higher_is_better"]))
        wide = wide_table(long, suite)
        for setting, group in wide.groupby(SETTING, sort=False, dropna=False):  # the wide table's order
            lines += _setting_table(suite, dict(zip(SETTING, setting)), group, part, better)
    return lines


def _setting_table(suite: str, setting: dict, group: pd.DataFrame, long: pd.DataFrame,
                   better: dict) -> list[str]:
    context = "" if setting["context"] in ("", None) else f", n = {setting['context']}"
    title = f"### {suite}: {dataset_label(setting['dataset'])} {setting['split']}, {setting['protocol']}{context} ({setting['source']})"
    rows = long
    for key in SETTING:
        rows = rows[rows[key].astype("string").fillna("") == str(setting[key])]
    sources = sorted({shown_path(r) if setting["source"] == "dyadbench" else r for r in rows["reference"]})
    metrics = [c for c in group.columns if c not in SETTING + ["model", *_ROW_LABELS]]
    header = "| column | " + " | ".join(cell(m) for m in group["model"]) + " |"
    out = [title, "", "Source: " + ", ".join(f"`{s}`" for s in sources) + ".",
           "Regenerate: `dyadbench leaderboard` (tables), `dyadbench report` (this page); "
           + ("each result file records the configuration that `dyadbench sweep` re-runs." if setting["source"]
              == "dyadbench" else "published rows transcribed from the paper."), "",
           header, "|---" * (len(group) + 1) + "|"]
    for label in (*_ROW_LABELS, *metrics):
        arrow = {True: " ↑", False: " ↓"}.get(better.get(label), "") if label in metrics else ""
        values = [cell(_plain(v)) for v in group[label]]
        if label in _ROW_LABELS and not any(values):
            continue
        out.append(f"| {label}{arrow} | " + " | ".join(values) + " |")
    return out + [""]


def _plain(value):
    """A pandas cell as a plain Python value (NA -> None, numpy scalars -> int/float/bool)."""
    if value is pd.NA or value is None:
        return None
    if hasattr(value, "item"):
        value = value.item()
    return value


def benchmark_sections(folder: Path) -> list[str]:
    """Markdown of every benchmark result in ``folder``: JSON results first-class, lone Markdown verbatim."""
    jsons = {p.stem: p for p in folder.glob("*.json")}
    lone = {p.stem: p for p in folder.glob("*.md") if p.stem not in jsons}
    lines = ["## Benchmarks", "",
             f"Each benchmark script in `benchmarks/` writes `{shown_path(folder)}/NAME.json` and `NAME.md` "
             "(`benchmarks/output.py`); the sections below are those files.", ""]
    for stem in sorted(set(jsons) | set(lone)):
        lines += _json_section(jsons[stem]) if stem in jsons else _legacy_section(lone[stem])
    return lines


def _json_section(path: Path) -> list[str]:
    try:
        record = strict_json.loads(path.read_text(encoding="utf-8"))
        command, seed, machine, markdown = (record["command"], record["seed"], record["machine"],
                                            record["markdown"])
    except (OSError, UnicodeDecodeError, ValueError, KeyError, TypeError) as exc:
        raise InputError(path, f"not a benchmark result file of benchmarks/output.py ({exc})") from None
    versions = ", ".join(f"{k} {v}" for k, v in sorted(machine["versions"].items()) if v is not None)
    threads = ", ".join(f"{k}={v}" for k, v in sorted(machine["threads"].items()) if v is not None) or "defaults"
    return [f"### {path.stem}", "",
            f"Source: `{shown_path(path)}`. Regenerate: `{command}` (seed {seed}).",
            f"Machine: {machine['usable_cores']} of {machine['cpu_count']} cores usable, {machine['platform']}, "
            f"Python {machine['python']}; {versions}; threads: {threads}.", "",
            *_demoted(markdown), ""]


def _legacy_section(path: Path) -> list[str]:
    return [f"### {path.stem}", "",
            f"Source: `{shown_path(path)}` (written before the benchmark scripts recorded their machine; the "
            "command that regenerates it is named in the file).", "",
            *_demoted(path.read_text(encoding="utf-8")), ""]


def _demoted(markdown: str) -> list[str]:
    """Markdown lines with headings moved three levels down (``#`` -> ``####``), fences left alone."""
    out, fenced = [], False
    for line in markdown.rstrip("\n").split("\n"):
        if line.startswith("```"):
            fenced = not fenced
        out.append("###" + line if line.startswith("#") and not fenced else line)
    return out


def render_page(results: list[Path], benchmarks: Path, paper: list[Path], command: str) -> str:
    """The whole page (see the module docstring); ``command`` is the line shown as its generator."""
    lines = ["# Results", "",
             f"Generated by `{command}` from committed files only; do not edit by hand (a test regenerates "
             "it byte for byte).", ""]
    lines += leaderboard_sections(results, paper)
    lines += benchmark_sections(benchmarks)
    return "\n".join(lines).rstrip("\n") + "\n"


def relative_command(results: list[Path], benchmarks: Path, out: Path, no_paper: bool) -> str:
    """The ``dyadbench report`` command line of a page, paths as :func:`shown_path` shows them; the page
    is named by its file name only, so a copy written elsewhere (e.g. by a test) has the same bytes."""
    parts = ["dyadbench report", *(shown_path(r) for r in results), "--benchmarks", shown_path(benchmarks),
             "--out", out.name]
    return " ".join(parts + (["--no-paper"] if no_paper else []))

