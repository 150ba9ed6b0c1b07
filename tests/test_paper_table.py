"""TIMAR's Table 1 layout (dyadbench.paper_table, `dyadbench leaderboard --table1`).

Expected numbers are worked out by hand from the values the hand-made result files hold (relative
change = 100 × (TIMAR − DualTalk) / |DualTalk|; FD, MSE, rPCC lower is better, SID higher, as the
DualTalk and TIMAR papers' arrows say), and the published block is checked against
leaderboards/paper_timar.csv read with the csv module, not through the code under test.
"""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import pandas as pd
import pytest
from click.testing import CliRunner

from dyadbench.cli import cli, main
from dyadbench.cli.leaderboard import PAPER_ROWS
from dyadbench.errors import InputError
from dyadbench.leaderboard import long_table
from dyadbench.paper_table import table1_frame, table1_texts
from dyadbench.results import DataRecord, EvalResult, ModelRecord, ProtocolRecord, TimingRecord

# raw values (the leaderboard scales them: MSE jaw x1e3, rPCC exp x1e2)
DUALTALK = {"fd_exp": 10.0, "fd_jaw": 0.0, "mse_jaw": 0.002, "sid_exp": 2.0, "rpcc_exp": 0.05}
TIMAR = {"fd_exp": 8.0, "fd_jaw": 0.001, "mse_jaw": 0.0025, "sid_exp": 2.5, "rpcc_exp": 0.06}
# by hand: (8-10)/10 = -20 % better; fd_jaw reference 0: undefined; (2.5-2)/2 = +25 % worse (MSE down is
# better); (2.5-2)/2 = +25 % better (SID up is better); (0.06-0.05)/0.05 = +20 % worse (rPCC down is better)
CHANGE = {"fd_exp": (-20.0, 1.0), "fd_jaw": (math.nan, math.nan), "mse_jaw": (25.0, 0.0), "sid_exp": (25.0, 1.0),
          "rpcc_exp": (20.0, 0.0)}


def write_result(folder, model: str, metrics: dict, *, split: str = "test", context: int = 0,
                 protocol: str = "streaming", dataset: str = "synthetic", cfg_scale: float = 1.0,
                 train: dict | None = None, name: str | None = None) -> None:
    """A hand-made result file, as `dyadbench eval` writes them, of raw ``metrics``."""
    folder.mkdir(parents=True, exist_ok=True)
    EvalResult(
        model=ModelRecord(model, "1", None, None, False, "flame56", {}),
        data=DataRecord(dataset, split, None, clips=2, items=4, train=train),
        protocol=ProtocolRecord(protocol, 1.0, context, "truncate", "masked", cfg_scale, 0),
        suite="dualtalk", metrics=metrics, scaled=dict(metrics), scaling={k: 1.0 for k in metrics}, per_clip=[],
        timing=TimingRecord(1.0, 1.0, 1, 1.0)).write(folder / f"{name or model}.json")


@pytest.fixture
def results(tmp_path):
    root = tmp_path / "results"
    write_result(root / "test/n0", "dualtalk", DUALTALK)
    write_result(root / "test/n0", "timar", TIMAR)
    write_result(root / "test/n0", "timar", {k: 99.0 for k in TIMAR}, cfg_scale=1.5, name="timar@cfg1.5")
    write_result(root / "test/n0", "dualtalk-offline", {k: 2 * v for k, v in DUALTALK.items()}, protocol="offline")
    write_result(root / "test/n0", "dualtalk", {k: 3 * v for k, v in DUALTALK.items()}, protocol="offline",
                 name="dualtalk-as-offline")  # not a Table 1 row: dualtalk is the streaming model
    return root


def _rows(frame: pd.DataFrame, split: str, context: str, model: str, kind: str) -> pd.Series:
    hit = frame[(frame["split"] == split) & (frame["context"] == context) & (frame["model"] == model)
                & (frame["kind"] == kind)]
    assert len(hit) == 1, (split, context, model, kind, len(hit))
    return hit.iloc[0]


def test_relative_change_and_verdict_per_column(results):
    frame, _ = table1_frame(long_table([results]))
    ours = frame[frame["source"] == "dyadbench"]
    change = _rows(ours, "test", "0", "timar", "change_pct")
    better = _rows(ours, "test", "0", "timar", "better")
    for key, (pct, verdict) in CHANGE.items():
        assert change[key] == pytest.approx(pct, nan_ok=True), key
        assert better[key] == pytest.approx(verdict, nan_ok=True), key
    assert change["versus"] == "dualtalk"
    timar = _rows(ours, "test", "0", "timar", "value")  # the default run, publication scaling; cfg1.5 stays out
    assert timar["fd_exp"] == 8.0 and timar["mse_jaw"] == pytest.approx(2.5) and timar["rpcc_exp"] == pytest.approx(6.0)
    offline = _rows(ours, "test", "offline", "dualtalk-offline", "value")
    assert offline["fd_exp"] == 20.0 and offline["file"].endswith("n0/dualtalk-offline.json")
    assert set(ours.loc[ours["context"] == "offline", "model"]) == {"dualtalk-offline"}  # DualTalk only
    assert _rows(ours, "test", "0", "dualtalk", "value")["fd_exp"] == 10.0


def test_missing_rows_are_shown_and_listed_never_filled(results):
    frame, missing = table1_frame(long_table([results]))
    ours = frame[frame["source"] == "dyadbench"]
    expected_rows = 2 * (1 + 3 * (1 + 2 * 3))  # splits x (offline dualtalk + contexts x (dualtalk + 2 x 3 rows))
    assert len(ours) == expected_rows
    assert "dyadbench synthetic test 0 timar-stream" in missing and "dyadbench synthetic ood 7 dualtalk" in missing
    assert "dyadbench synthetic ood offline dualtalk-offline" in missing
    assert "dyadbench synthetic test 0 timar" not in missing
    assert len(missing) == 2 * 10 - 3  # 10 value rows per split, 3 present
    stream = _rows(ours, "test", "0", "timar-stream", "value")
    assert stream["marks"] == "missing" and stream[list(CHANGE)].isna().all()
    assert _rows(ours, "test", "3", "timar", "change_pct")[list(CHANGE)].isna().all()
    md = table1_texts(long_table([results]))[0]["table1_dyadbench_synthetic.md"]
    assert "| | timar-stream (missing) | — |" in md.replace("|  |", "| |")


def test_cli_writes_the_tables_byte_for_byte_again_and_lists_missing_rows(results, tmp_path):
    outs = [tmp_path / "a", tmp_path / "b"]
    for out in outs:
        run = CliRunner().invoke(cli, ["leaderboard", str(results), "--table1", "--out", str(out)])
        assert run.exit_code == 0, run.output
        assert "missing Table 1 row (shown as missing): dyadbench synthetic ood 0 timar" in run.stderr
    names = sorted(p.name for p in outs[0].glob("table1_*"))
    assert names == [f"table1_{t}.{ext}" for t in ("dyadbench_synthetic", "paper_dualtalk")
                     for ext in ("csv", "md", "tex")]
    for name in names:
        assert (outs[0] / name).read_bytes() == (outs[1] / name).read_bytes(), name
    run = CliRunner().invoke(cli, ["leaderboard", str(results), "--out", str(outs[0])])  # without --table1
    assert run.exit_code == 0 and sorted(p.name for p in outs[0].glob("table1_*")) == names


def test_flagged_and_non_causal_rows_are_marked(tmp_path):
    write_result(tmp_path, "dualtalk", DUALTALK, train={"overlap": 3})
    write_result(tmp_path, "timar", TIMAR)
    record = json.loads((tmp_path / "timar.json").read_text())
    record["protocol"]["speech_norm"] = "clip"  # whole-clip waveform statistics: the published protocol
    (tmp_path / "timar.json").write_text(json.dumps(record))
    frame, _ = table1_frame(long_table([tmp_path]))
    assert _rows(frame, "test", "0", "dualtalk", "value")["marks"] == "train-overlap=3"
    assert _rows(frame, "test", "0", "timar", "value")["marks"] == "speech_norm=clip"
    texts, _ = table1_texts(long_table([tmp_path]))
    md, tex = texts["table1_dyadbench_synthetic.md"], texts["table1_dyadbench_synthetic.tex"]
    assert "| dualtalk‡ |" in md and "| timar§ |" in md and "not strictly causal" in md
    assert r"dualtalk$^\ddagger$ &" in tex and r"timar$^\S$ &" in tex


def test_latex_escapes_names_and_marks_better_changes_in_bold(tmp_path):
    folder = tmp_path / "runs_50%"
    write_result(folder, "dualtalk", DUALTALK, dataset="my_data")
    write_result(folder, "timar", TIMAR, dataset="my_data")
    tex = table1_texts(long_table([folder]))[0]["table1_dyadbench_my_data.tex"]
    body = [line for line in tex.splitlines() if not line.startswith("%")]
    assert r"\emph{my\_data test (dyadbench)}" in tex and r"runs\_50\%" in tex
    for line in body:
        assert "%" not in line.replace(r"\%", ""), line
        assert "_" not in line.replace(r"\_", ""), line
    change = next(line for line in body if r"$\Delta$ vs dualtalk" in line).split(" & ")[2:]
    assert change[0] == r"\textbf{$-20.0$\%}"  # FD exp: better
    assert r"$+20.0$\%" in change and r"\textbf{$+20.0$\%}" not in change  # rPCC exp: worse, not bold


def test_two_runs_for_one_row_are_refused_naming_both(results, tmp_path, capsys):
    write_result(results / "again", "timar", TIMAR, train={"overlap": 1})
    with pytest.raises(InputError, match="several runs fill one row") as err:
        table1_frame(long_table([results]))
    assert "test/n0/timar.json" in str(err.value) and "again/timar.json" in str(err.value)
    with pytest.raises(SystemExit) as exit_:
        main(["leaderboard", str(results), "--table1", "--out", str(tmp_path / "x")])
    err = capsys.readouterr().err
    assert exit_.value.code == 2 and err.startswith("error: ") and len(err.strip().splitlines()) == 1, err
    assert not (tmp_path / "x").exists() or not list((tmp_path / "x").iterdir())  # nothing written


def _published() -> list[dict]:
    with open(PAPER_ROWS, newline="", encoding="utf-8") as f:
        return list(csv.DictReader(f))


def test_published_block_is_paper_timar_csv(tmp_path):
    write_result(tmp_path, "timar", TIMAR)
    frame, missing = table1_frame(long_table([tmp_path], [PAPER_ROWS]))
    paper = frame[frame["source"] == "paper"]
    assert not [m for m in missing if m.startswith("paper")]  # every published row of the layout is there
    shown = 0
    for row in _published():
        streaming = row["protocol"] == "streaming" and row["model"] in ("DualTalk-official", "DualTalk-retrained",
                                                                        "TIMAR")
        offline = row["protocol"] == "offline" and row["model"] in ("DualTalk-official", "DualTalk-retrained")
        if not (streaming or offline):
            continue
        value = _rows(paper, row["split"], row["context"] or "offline", row["model"], "value")
        for key in ("fd_exp", "fd_jaw", "pfd_pose", "mse_exp", "sid_pose", "rpcc_exp", "rpcc_pose"):
            assert value[key] == pytest.approx(float(row[key]), abs=1e-12), (row["model"], key)
        shown += 1
    assert shown == 2 * (2 + 3 * 3)  # splits x (2 offline DualTalk rows + 3 contexts x 3 rows)
    # TIMAR against DualTalk* (official), test n = 0, FD exp: (9.61 - 13.93) / 13.93 = -31.01 %, better;
    # test n = 3, rPCC pose: (2.19 - 2.16) / 2.16 = +1.39 %, worse
    assert _rows(paper, "test", "0", "TIMAR", "change_pct")["fd_exp"] == pytest.approx(-31.0122, abs=1e-4)
    assert _rows(paper, "test", "0", "TIMAR", "better")["fd_exp"] == 1.0
    assert _rows(paper, "test", "3", "TIMAR", "change_pct")["rpcc_pose"] == pytest.approx(1.3889, abs=1e-4)
    assert _rows(paper, "test", "3", "TIMAR", "better")["rpcc_pose"] == 0.0
    md = table1_texts(long_table([tmp_path], [PAPER_ROWS]))[0]["table1_paper_dualtalk.md"]
    assert "| -31.0% ✓ |" in md and "| +1.4% ✗ |" in md


REPO = Path(__file__).resolve().parents[1]


def test_committed_table1_files_are_rebuilt_exactly_from_committed_results(monkeypatch):
    """What `dyadbench leaderboard results --latex --table1 --out leaderboards` writes for Table 1."""
    monkeypatch.chdir(REPO)
    texts, _ = table1_texts(long_table([Path("results")], [PAPER_ROWS]))
    committed = sorted(p.name for p in (REPO / "leaderboards").glob("table1_*"))
    assert committed == sorted(texts)
    for name in committed:
        assert (REPO / "leaderboards" / name).read_bytes() == texts[name].encode("utf-8"), name
