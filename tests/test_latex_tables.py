"""The committed LaTeX tables compile standalone with booktabs: compiled when a TeX engine is on PATH,
otherwise checked for structure (balanced environments, cells per row = the tabular's columns, booktabs
rules, escaped underscores and percent signs, bold only in ranked model rows)."""

from __future__ import annotations

import re
import shutil
import subprocess
from pathlib import Path

import pytest

from dyadbench.leaderboard import latex_table, long_table, wide_table
from tests.test_figures import write_result

REPO = Path(__file__).resolve().parents[1]
TABLES = sorted((REPO / "leaderboards").glob("*.tex"))
ENGINE = next((e for e in ("pdflatex", "lualatex", "xelatex") if shutil.which(e)), None)


def body(tex: str) -> list[str]:
    """The lines of ``tex`` that are not comments."""
    return [line for line in tex.splitlines() if line.strip() and not line.lstrip().startswith("%")]


def cells(row: str) -> int:
    """Columns a tabular row spans: its cells, a ``\\multicolumn{k}`` counting k."""
    row = row.removesuffix(r"\\").strip()
    parts = re.split(r"(?<!\\)&", row)
    return sum(int(m.group(1)) if (m := re.match(r"\s*\\multicolumn\{(\d+)\}", p)) else 1 for p in parts)


def check_structure(tex: str, name: str) -> None:
    lines = body(tex)
    begins = re.findall(r"\\begin\{(\w+)\}", tex)
    assert begins and sorted(begins) == sorted(re.findall(r"\\end\{(\w+)\}", tex)), name
    depth = 0
    for line in lines:
        if line.startswith(r"\begin{tabular}"):
            assert depth == 0, name
            depth, spec = 1, re.match(r"\\begin\{tabular\}\{([lrc|]+)\}", line).group(1)
            columns, rules = len(spec.replace("|", "")), []
        elif line.startswith(r"\end{tabular}"):
            assert rules[0] == "toprule" and rules[-1] == "bottomrule" and "midrule" in rules, name
            depth = 0
        elif line.rstrip("\\ ").strip() in (r"\toprule", r"\midrule", r"\bottomrule"):
            rules.append(line.strip()[1:])
        else:
            assert depth == 1 and line.endswith(r"\\"), (name, line)
            assert cells(line) == columns, (name, line)
            text = re.sub(r"\$[^$]*\$", "", line)  # outside math
            assert not re.search(r"(?<!\\)[_%#]", text), (name, line)
    assert depth == 0, name


@pytest.mark.parametrize("path", TABLES, ids=lambda p: p.name)
def test_committed_latex_has_booktabs_structure(path):
    check_structure(path.read_text(encoding="utf-8"), path.name)


@pytest.mark.skipif(ENGINE is None, reason="no TeX engine on PATH (structure checked instead)")
@pytest.mark.parametrize("path", TABLES, ids=lambda p: p.name)
def test_committed_latex_compiles_standalone(path, tmp_path):
    document = (r"\documentclass{article}\usepackage{booktabs}\usepackage{amssymb}\begin{document}"
                f"\n{path.read_text(encoding='utf-8')}\n" + r"\end{document}")
    (tmp_path / "t.tex").write_text(document, encoding="utf-8")
    run = subprocess.run([ENGINE, "-interaction=nonstopmode", "-halt-on-error", "t.tex"], cwd=tmp_path,
                         capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stdout[-2000:]


def test_the_checker_catches_what_it_should():
    good = "\\begin{tabular}{lr}\n\\toprule\nModel & FD \\\\\n\\midrule\na & 1.00 \\\\\n\\bottomrule\n\\end{tabular}\n"
    check_structure(good, "good")
    for bad in (good.replace("a & 1.00", "a & 1.00 & 2.00"), good.replace("Model", "my_model"),
                good.replace("\\bottomrule\n", ""), good.replace("\\end{tabular}\n", "")):
        with pytest.raises(AssertionError):
            check_structure(bad, "bad")


def test_bold_only_in_ranked_model_rows_and_uncertainty_as_plus_minus(tmp_path):
    write_result(tmp_path, "a", 0, 5.0)
    write_result(tmp_path, "b", 0, 6.0)
    write_result(tmp_path, "oracle", 0, 0.0, oracle=True)
    tex = latex_table(wide_table(long_table([tmp_path])))
    check_structure(tex, "fresh")
    rows = {line.split(" & ")[0]: line for line in body(tex) if " & " in line}
    assert r"\textbf{5.00}" in rows["a"] and r"\textbf" not in rows["b"] and r"\textbf" not in rows[r"oracle$^\dagger$"]
    # uncertainty columns, when the wide table carries them, print as value $\pm$ se in the same cell
    wide = wide_table(long_table([tmp_path])).assign(fd_exp_se=0.25)
    tex = latex_table(wide)
    check_structure(tex, "se")
    assert r"5.00} $\pm$ 0.25 &" in tex


def test_l2l_table_scales_jaw_and_pose_and_never_bolds_references():
    tex = (REPO / "leaderboards" / "l2l_wide.tex").read_text(encoding="utf-8")
    lines = body(tex)
    header = lines[2].removesuffix(r" \\").split(" & ")
    assert r"L2 jaw$\downarrow$ $\times10^{3}$" in header and r"Var pose $\times10^{3}$" in header
    assert not [h for h in header if "GT" in h]  # the ground truth is a row, not columns
    rows = {line.split(" & ")[0]: line.removesuffix(r" \\").split(" & ") for line in lines if " & " in line}
    truth = rows[r"\emph{ground truth}"]
    assert not any(r"\textbf" in c for c in truth + rows[r"oracle$^\dagger$"])
    # hand-read from results/l2l/test/n1/mean-frame.json: l2_jaw 0.0002004 -> 0.20, l2_pose 0.0010602 -> 1.06
    mean_frame = rows["mean-frame"]
    assert mean_frame[header.index(r"L2 jaw$\downarrow$ $\times10^{3}$")] == "0.20"
    assert mean_frame[header.index(r"L2 pose$\downarrow$ $\times10^{3}$")] == r"\textbf{1.06}"
    # no column of descriptive values (Var, SI-GT...) is ever bolded
    for h in (r"Var exp", r"Var pose $\times10^{3}$"):
        assert not any(r"\textbf" in r[header.index(h)] for r in rows.values() if len(r) == len(header))
