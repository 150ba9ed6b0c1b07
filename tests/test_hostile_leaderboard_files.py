"""Hostile inputs for written files: leaderboards never stale or built from nothing, published-rows CSVs
checked cell by cell, files readable under the user's umask, strict JSON that old readers still load."""

from __future__ import annotations

import json
import math
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

from dyadbench import atomic, strict_json
from dyadbench.cli import main
from dyadbench.cli.leaderboard import PAPER_ROWS
from dyadbench.errors import InputError
from dyadbench.leaderboard import long_table, table_texts
from dyadbench.results import load_result

REPO = Path(__file__).resolve().parents[1]
#: A committed result written before strict JSON: its rPCC metrics are bare NaN (the zero model has no variance).
OLD_NAN_RESULT = REPO / "results" / "synthetic" / "test" / "n7" / "zero.json"
DUALTALK_RESULT = REPO / "results" / "synthetic" / "test" / "n0" / "mime.json"
L2L_RESULT = REPO / "results" / "l2l" / "test" / "n1" / "mime.json"


def _snapshot(folder: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(folder.iterdir())}


def _fail(argv: list[str], capsys) -> str:
    """Run the CLI expecting a user error; the one-line message (stderr)."""
    with pytest.raises(SystemExit) as exc:
        main(argv)
    err = capsys.readouterr().err
    assert exc.value.code == 2, err
    assert "Traceback" not in err and len(err.strip().splitlines()) == 1, err
    return err


@pytest.fixture
def results(tmp_path):
    """A results folder with one dualtalk-suite and one l2l-suite result (committed files)."""
    root = tmp_path / "results"
    for source in (DUALTALK_RESULT, L2L_RESULT):
        target = root / source.relative_to(REPO / "results")
        target.parent.mkdir(parents=True)
        shutil.copy(source, target)
    return root


@pytest.fixture
def built(results, tmp_path):
    """OUT folder holding a complete build (with LaTeX) of ``results`` and an unrelated file."""
    out = tmp_path / "out"
    main(["leaderboard", str(results), "--out", str(out), "--latex"])
    (out / "notes.txt").write_text("not a table")
    return out


# --- leaderboard: no build from nothing, no stale tables ------------------------------------------------


def test_an_empty_results_folder_is_refused_and_the_previous_tables_kept(built, tmp_path, capsys):
    before = _snapshot(built)
    empty = tmp_path / "empty"
    (empty / "sub").mkdir(parents=True)
    err = _fail(["leaderboard", str(empty), "--out", str(built), "--latex"], capsys)
    assert err == f"error: {empty}: no result files (*.json) in this folder\n"
    assert _snapshot(built) == before


def test_tables_of_a_suite_no_longer_present_are_removed(results, built, tmp_path, capsys):
    assert {"dualtalk_wide.csv", "dualtalk_wide.tex", "l2l_wide.csv", "l2l_wide.tex"} <= set(_snapshot(built))
    shutil.rmtree(results / "synthetic")  # the dualtalk-suite result is gone
    main(["leaderboard", str(results), "--out", str(built), "--no-paper"])  # and no --latex this time
    printed = capsys.readouterr().out
    fresh = tmp_path / "fresh"
    main(["leaderboard", str(results), "--out", str(fresh), "--no-paper"])
    after = _snapshot(built)
    assert set(after) == {"long.csv", "l2l_wide.csv", "notes.txt"}  # the unrelated file is not the build's
    assert {k: v for k, v in after.items() if k != "notes.txt"} == _snapshot(fresh)
    for name in ("dualtalk_wide.csv", "dualtalk_wide.tex", "l2l_wide.tex"):
        assert f"removed {built / name} (not part of this build)" in printed


def test_a_failure_while_writing_the_tables_leaves_the_previous_set(results, built, monkeypatch):
    before = _snapshot(built)
    tables = table_texts(long_table([results]), latex=True)

    class Unwritable(str):
        def encode(self, *args, **kwargs):
            raise OSError("disk full")

    last = sorted(tables)[-1]
    tables[last] = Unwritable(tables[last])
    with pytest.raises(OSError, match="disk full"):
        atomic.write_texts({built / name: text for name, text in tables.items()})
    assert _snapshot(built) == before  # no table replaced, no temporary file left


# --- published-rows CSV ------------------------------------------------------------------------------


HEADER = "source,reference,model,dataset,split,protocol,context,fd_exp,mse_exp\n"


@pytest.mark.parametrize("text,problem", [
    (HEADER + "paper,T1,A,dualtalk,test,streaming,0,1.5,2\npaper,T1,B,dualtalk,test,streaming,0,1.2,n/a\n",
     "line 3, column 'mse_exp': 'n/a' is not a finite number"),
    (HEADER + "paper,T1,A,dualtalk,test,streaming,0,inf,2\n", "line 2, column 'fd_exp': 'inf' is not a finite number"),
    (HEADER + "paper,T1,A,dualtalk,test,streaming,seven,1,2\n",
     "line 2, column 'context': 'seven' is not a whole number"),
    (HEADER + "paper,T1,,dualtalk,test,streaming,0,1,2\n", "line 2, column 'model': empty"),
    (HEADER + "paper,T1,A,dualtalk,test,streaming,0,1\n", "line 2 has 8 cells, the header has 9"),
    ("source,reference,model,dataset,split,protocol,fd_exp\npaper,T1,A,dualtalk,test,streaming,1\n",
     "missing columns context"),
    (HEADER.replace("mse_exp", "fd_exp") + "paper,T1,A,dualtalk,test,streaming,0,1,2\n", "repeated columns fd_exp"),
    (HEADER, "no published rows below the header"),
    ("", "empty file (expected a header line and published rows)"),
    ("\n\n", "empty file (expected a header line and published rows)"),
])
def test_bad_published_rows_name_the_file_line_and_column(results, tmp_path, capsys, text, problem):
    paper = tmp_path / "published.csv"
    paper.write_text(text)
    out = tmp_path / "never"
    err = _fail(["leaderboard", str(results), "--paper", str(paper), "--out", str(out)], capsys)
    assert err == f"error: {paper}: {problem}\n"
    assert not out.exists()


def test_empty_published_cells_are_missing_values():
    paper_text = PAPER_ROWS.read_text().splitlines()
    assert any(",," in line for line in paper_text)  # Table 2 rows have no context
    long = long_table([L2L_RESULT], [PAPER_ROWS])
    offline = long[(long["source"] == "paper") & (long["protocol"] == "offline")]
    assert offline["context"].isna().all() and offline["scaled"].notna().all()


# --- file modes under the user's umask ---------------------------------------------------------------


WRITE_EVERYTHING = textwrap.dedent("""
    import os, sys
    os.umask(int(sys.argv[1], 8))
    import numpy as np
    from dyadbench import atomic
    from dyadbench.cli import main
    from dyadbench.results import load_result
    out = sys.argv[2]
    load_result(sys.argv[3]).write(out + "/result.json")
    atomic.save_npy(out + "/predictions/synth_test_00000_speaker1.npy", np.zeros((3, 56), np.float32))
    atomic.make_temp_dir(out, ".staging-")
    main(["leaderboard", sys.argv[3], "--out", out + "/leaderboards", "--latex"])
""")


@pytest.mark.parametrize("umask,file_mode,dir_mode", [("022", 0o644, 0o755), ("002", 0o664, 0o775)])
def test_written_files_get_the_mode_of_the_umask(tmp_path, umask, file_mode, dir_mode):
    proc = subprocess.run([sys.executable, "-c", WRITE_EVERYTHING, umask, str(tmp_path), str(DUALTALK_RESULT)],
                          capture_output=True, text=True, cwd=REPO)
    assert proc.returncode == 0, proc.stderr
    files = [p for p in tmp_path.rglob("*") if p.is_file()]
    names = {p.relative_to(tmp_path).as_posix() for p in files}
    assert {"result.json", "predictions/synth_test_00000_speaker1.npy", "leaderboards/long.csv",
            "leaderboards/dualtalk_wide.csv", "leaderboards/dualtalk_wide.tex"} <= names
    assert {p.relative_to(tmp_path).as_posix(): oct(p.stat().st_mode & 0o777) for p in files} == {
        n: oct(file_mode) for n in names}
    staging = [p for p in tmp_path.iterdir() if p.name.startswith(".staging-")]
    assert len(staging) == 1 and staging[0].stat().st_mode & 0o777 == dir_mode


# --- strict JSON ---------------------------------------------------------------------------------------


def _no_constants(name: str):
    raise ValueError(f"non-standard JSON constant {name}")


def test_a_nan_metric_is_written_as_strict_json_and_read_back_as_nan(tmp_path):
    old = load_result(OLD_NAN_RESULT)
    assert "NaN" in OLD_NAN_RESULT.read_text() and math.isnan(old.metrics["rpcc_exp"])
    path = old.write(tmp_path / "result.json")
    text = path.read_text()
    doc = json.loads(text, parse_constant=_no_constants)  # a strict parser accepts it
    assert doc["metrics"]["rpcc_exp"] is None and doc["nonfinite"]["/metrics/rpcc_exp"] == "nan"
    assert list(doc)[-1] == "nonfinite"
    new = load_result(path)
    assert math.isnan(new.metrics["rpcc_exp"]) and math.isnan(new.scaled["rpcc_exp"])
    # the old file (bare NaN) and the new one (null + nonfinite) load to the same result
    assert strict_json.dumps(new.to_dict()) == strict_json.dumps(old.to_dict())


def test_infinities_and_nans_anywhere_round_trip_exactly(tmp_path):
    result = load_result(DUALTALK_RESULT)
    result.metrics["fd_exp"] = math.inf
    result.scaled["fd_exp"] = -math.inf
    result.per_clip = [{"clip": "a", "mse_jaw": 0.5}, {"clip": "b", "mse_jaw": np.float32("nan")}]
    result.coverage["odd/key~"] = [1.0, math.inf]
    path = result.write(tmp_path / "result.json")
    doc = json.loads(path.read_text(), parse_constant=_no_constants)
    assert doc["per_clip"] == {"columns": ["clip", "mse_jaw"], "rows": [["a", 0.5], ["b", None]]}
    assert doc["nonfinite"] == {"/metrics/fd_exp": "inf", "/scaled/fd_exp": "-inf", "/per_clip/rows/1/1": "nan",
                                "/coverage/odd~1key~0/1": "inf"}
    back = load_result(path)
    assert back.metrics["fd_exp"] == math.inf and back.scaled["fd_exp"] == -math.inf
    assert math.isnan(back.per_clip[1]["mse_jaw"]) and back.coverage["odd/key~"] == [1.0, math.inf]


@pytest.mark.parametrize("nonfinite,problem", [
    ({"/metrics/fd_exp": "nan"}, "names a value that is not null"),
    ({"/metrics/no_such_metric": "nan"}, "names no value"),
    ({"/metrics/fd_exp": "NaN!"}, "bad 'nonfinite' entry"),
    ("nan", "'nonfinite' must be an object"),
])
def test_a_malformed_nonfinite_map_is_an_error_naming_the_file(tmp_path, nonfinite, problem):
    doc = json.loads(DUALTALK_RESULT.read_text())
    doc["nonfinite"] = nonfinite
    path = tmp_path / "result.json"
    path.write_text(json.dumps(doc))
    with pytest.raises(InputError, match=problem) as exc:
        load_result(path)
    assert str(exc.value).startswith(f"{path}: not readable JSON")


def test_strict_json_refuses_what_it_cannot_record():
    assert math.isnan(strict_json.loads(strict_json.dumps({"a": [np.float64(np.nan)]}))["a"][0])
    with pytest.raises(ValueError, match="cannot record"):
        strict_json.dumps([math.nan])
    with pytest.raises(ValueError, match="cannot record"):
        strict_json.dumps({"nonfinite": {}, "x": math.inf})


def test_every_committed_result_file_still_loads():
    files = sorted((REPO / "results").rglob("*.json"))
    assert len(files) >= 90
    for path in files:
        load_result(path)
