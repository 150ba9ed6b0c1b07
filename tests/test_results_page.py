"""The results page (RESULTS.md), the benchmark result files and the README's figures all have a source.

- RESULTS.md regenerates byte for byte from the committed result and benchmark files;
- every benchmark script writes its result through ``benchmarks/output.py`` (checked in the source, and
  by one real quick run whose files are read back and rendered);
- the README holds no Markdown table of figures and no paragraph with a figure that does not name a
  committed source file (or say that it is to be regenerated, with the command).
"""

from __future__ import annotations

import ast
import csv
import json
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

from dyadbench.cli import main as cli_main
from dyadbench.results_page import benchmark_sections, cell

ROOT = Path(__file__).resolve().parents[1]
BENCHMARKS = ROOT / "benchmarks"


@pytest.fixture
def at_root(monkeypatch):
    monkeypatch.chdir(ROOT)


def test_results_md_regenerates_byte_for_byte(at_root, tmp_path):
    out = tmp_path / "RESULTS.md"
    cli_main(["report", "results", "--benchmarks", "benchmarks/results", "--out", str(out)])
    assert out.read_bytes() == (ROOT / "RESULTS.md").read_bytes(), (
        "RESULTS.md is stale: run `dyadbench report results --benchmarks benchmarks/results --out RESULTS.md`")


def test_results_md_shows_the_committed_leaderboard_values():
    """Cells of RESULTS.md against leaderboards/dualtalk_wide.csv read independently with the csv module."""
    with (ROOT / "leaderboards" / "dualtalk_wide.csv").open(newline="") as f:
        rows = [r for r in csv.DictReader(f)
                if (r["source"], r["dataset"], r["split"], r["context"]) == ("dyadbench", "synthetic", "test", "7")]
    page = (ROOT / "RESULTS.md").read_text()
    section = page.split("### dualtalk: synthetic (v1) test, streaming, n = 7 (dyadbench)")[1].split("\n### ")[0]
    header = next(line for line in section.split("\n") if line.startswith("| column |"))
    models = [c.strip() for c in header.strip("|").split("|")][1:]
    for metric in ("mse_pose", "rpcc_exp", "fd_exp"):
        line = next(x for x in section.split("\n") if x.startswith(f"| {metric} "))
        shown = dict(zip(models, [c.strip() for c in line.strip("|").split("|")][1:]))
        for r in rows:
            assert shown[r["model"]] == ("%.4g" % float(r[metric]) if r[metric] else "–"), (metric, r["model"])


def test_cell_formatting():
    assert cell(0.405748) == "0.4057"
    assert cell(16.2810201) == "16.28"
    assert cell(1066) == "1066"
    assert cell(float("nan")) == "–"
    assert cell(None) == "–"
    assert cell(True) == "yes" and cell(False) == ""
    assert cell("a|b") == "a\\|b"


# --- every benchmark script writes its result file through benchmarks/output.py -------------------------


def _scripts() -> list[Path]:
    return sorted(BENCHMARKS.glob("bench_*.py"))


@pytest.mark.parametrize("script", _scripts(), ids=lambda p: p.name)
def test_benchmark_script_writes_through_the_shared_helper(script):
    tree = ast.parse(script.read_text())
    imported = {alias.name for node in ast.walk(tree) if isinstance(node, ast.ImportFrom) and node.module == "output"
                for alias in node.names}
    assert "write_result" in imported, f"{script.name} does not import output.write_result"
    calls = [node for node in ast.walk(tree) if isinstance(node, ast.Call)
             and isinstance(node.func, ast.Name) and node.func.id == "write_result"]
    assert calls, f"{script.name} never calls write_result"
    main = next(node for node in tree.body if isinstance(node, ast.FunctionDef) and node.name == "main")
    assert any(isinstance(node, ast.Call) and getattr(node.func, "id", None) == "write_result"
               for node in ast.walk(main)), f"{script.name}: main() does not write its result"
    own_writer = [node for node in ast.walk(tree) if isinstance(node, ast.ImportFrom) and node.module == "dyadbench"
                  and any(alias.name == "atomic" for alias in node.names)]
    assert not own_writer, f"{script.name} writes files itself (dyadbench.atomic) instead of through write_result"


def test_quick_benchmark_run_writes_json_and_markdown_that_the_report_reads(tmp_path):
    out = tmp_path / "retrieval_index"
    env = {**os.environ, "DYADBENCH_CACHE": str(tmp_path / "cache")}
    args = ["benchmarks/bench_retrieval_index.py", "--train", "3", "--test", "1", "--out", str(out)]
    subprocess.run([sys.executable, *args], cwd=ROOT, env=env, check=True, capture_output=True, timeout=300)
    record = json.loads((tmp_path / "retrieval_index.json").read_text())
    assert record["benchmark"] == "bench_retrieval_index.py"
    assert record["command"] == "python " + " ".join(args)
    assert record["seed"] == 0
    assert record["machine"]["cpu_count"] == os.cpu_count()
    assert record["machine"]["versions"]["numpy"] == __import__("numpy").__version__
    assert set(record["machine"]["threads"]) >= {"OMP_NUM_THREADS", "NUMBA_NUM_THREADS"}
    table = record["markdown"]
    assert re.search(r"^kdtree-pca .* 100\.0%$", table, re.M), table
    markdown = (tmp_path / "retrieval_index.md").read_text()
    assert markdown.startswith(table) and f"Regenerate: `{record['command']}` (seed 0)" in markdown
    page = "\n".join(benchmark_sections(tmp_path))
    assert "### retrieval_index" in page and f"`{record['command']}`" in page and "kdtree-pca" in page
    assert list(tmp_path.glob(".*.tmp")) == []  # atomic writes leave no temporary file


# --- the README cites no figure without a source ---------------------------------------------------------

#: A figure: a decimal number, or a number followed by × or % (not "4 × 128", a shape).
FIGURE = re.compile(r"(?<![\w.])(\d+\.\d+(?!\.\d)|\d+(?:\.\d+)?\s?(?:×(?!\s?\d)|%))")
#: Names that contain digits but are no figures.
NAMES = re.compile(r"wav2vec 2\.0|TFM-SE-64|SE-\d+")
#: A named source: a committed result, leaderboard or benchmark file, RESULTS.md (a section of it), or
#: the code file that defines a constant.
SOURCE = re.compile(r"(?:benchmarks/results|results|leaderboards)/[\w./@-]*\w|RESULTS\.md(?=#|\b)"
                    r"|(?:dyadbench|models|baselines|tests)/[\w/]+\.py")
REGENERATE = re.compile(r"\(to be regenerated: `[^`]+`\)")
COMMAND = re.compile(r"^\s*(?:dyadbench|python|pip|OMP_NUM_THREADS)\b")


def readme_blocks(text: str) -> list[dict]:
    """Paragraphs, list items and tables of a Markdown text outside fenced code and command lines.

    A list item's parent is the item that encloses it (smaller indentation), or for a top-level item the
    paragraph that introduces the list (the last paragraph before it under the same heading); a table's
    parent is the paragraph directly above it. Command lines
    (``dyadbench``, ``python``, ``pip`` ..., with their continuation lines) are skipped. Each block: first line number, its lines, parent block or None.
    """
    blocks: list[dict] = []
    current, lead, items, fenced, in_command = None, None, [], False, False
    for number, line in enumerate(text.split("\n"), 1):
        if line.lstrip().startswith("```"):
            fenced = not fenced
            continue
        if fenced or (in_command and line.strip()) or COMMAND.match(line):
            in_command = line.rstrip().endswith("\\")
            continue
        in_command = False
        if line.startswith("#"):
            current, items, lead = None, [], None
            continue
        if not line.strip():
            current = None
            continue
        indent = len(line) - len(line.lstrip())
        is_item = re.match(r"\s*(?:[-*]|\d+\.)\s", line) is not None
        is_table = line.lstrip().startswith("|")
        if is_item or current is None or is_table != current["table"]:
            items = [b for b in items if b["indent"] < indent] if not is_table else items
            if is_table:
                parent = current
            else:
                parent = items[-1] if items else (lead if is_item else None)
            current = {"line": number, "lines": [], "indent": indent, "table": is_table, "item": is_item,
                       "parent": parent}
            blocks.append(current)
            if is_item:
                items.append(current)
            else:
                lead = None if is_table else current
        current["lines"].append(line)
    return blocks


def block_sources(block: dict | None) -> list[str]:
    """Source files named by a block or by the blocks that enclose it, that exist in the repository."""
    found = []
    while block is not None:
        found += [s for s in SOURCE.findall("\n".join(block["lines"])) if (ROOT / s).exists()]
        block = block["parent"]
    return found


def figures(block: dict) -> list[str]:
    text = re.sub(r"`[^`]*`", "", "\n".join(block["lines"]))
    return FIGURE.findall(NAMES.sub("", text))


def unsourced(text: str) -> list[str]:
    """Blocks with a figure but no named source and no "(to be regenerated: `command`)", and tables with
    figures at all (tables of results belong in RESULTS.md)."""
    bad = []
    for block in readme_blocks(text):
        found = figures(block)
        if not found:
            continue
        if block["table"]:
            bad.append(f"line {block['line']}: a table of figures ({', '.join(found[:4])}); link RESULTS.md instead")
        elif not block_sources(block) and not REGENERATE.search("\n".join(block["lines"])):
            bad.append(f"line {block['line']}: {', '.join(found[:4])} without a source file")
    return bad


def test_readme_cites_no_figure_without_a_source():
    bad = unsourced((ROOT / "README.md").read_text())
    assert not bad, "README figures without a source:\n" + "\n".join(bad)


def test_readme_check_catches_unsourced_figures_and_tables():
    text = ("Intro.\n\n- **Result** (`benchmarks/results/sfms_l2l.md`):\n  - nested FD 7.14 vs 9.35.\n"
            "- FD exp 3.86 on test.\n\nSpeed: 3.13× faster (to be regenerated: `python benchmarks/x.py`).\n\n"
            "Source `RESULTS.md`:\n\n| a | b |\n|---|---|\n| 1.5 | 2 |\n\n"
            "    dyadbench sweep --cfg-scale 1.5 \\\n      --threads 1.0\n\n"
            "Named from `benchmarks/results/no_such_file.md`: 0.5.\n\nwav2vec 2.0 and a 4 × 128 array.\n")
    assert unsourced(text) == ["line 5: 3.86 without a source file",
                               "line 11: a table of figures (1.5); link RESULTS.md instead",
                               "line 18: 0.5 without a source file"]
