"""Provenance staleness (dyadbench.staleness): result files classified as current, stale (with the reason) or
unverified; `leaderboard` warns about stale rows with unchanged tables; `sweep --stale` re-runs exactly them."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from dyadbench.cli import main
from dyadbench.leaderboard import long_table, table_texts
from dyadbench.staleness import CURRENT, STALE, UNVERIFIED, Checker
from tests.hostile_cli import run_cli, write_dialogues
from tests.protocol_clips import isolated_cache  # noqa: F401

FAKE_DIGEST = "0" * 64


@pytest.fixture(scope="module")
def swept(tmp_path_factory) -> Path:
    """A sweep over a small DualTalk root (2 test and 2 train dialogues of 4 s): mean-frame and zero at n=0
    and n=3, without per-clip rows. Shared read-only; tests copy what they change."""
    root = tmp_path_factory.mktemp("data")
    write_dialogues(root / "test", "test", 2)
    write_dialogues(root / "train", "train", 2)
    out = tmp_path_factory.mktemp("results")
    with pytest.MonkeyPatch.context() as mp:  # the per-session cache of isolated_cache
        mp.setenv("DYADBENCH_CACHE", str(tmp_path_factory.getbasetemp() / "dyadbench-cache"))
        try:
            main(["sweep", "--models", "mean-frame,zero", "--splits", "test", "--contexts", "0,3", "--data",
                  str(root), "--out", str(out), "--no-per-clip"])
        except SystemExit as exc:
            assert exc.code in (0, None)
    return out / "dualtalk" / "test"


def edited(source: Path, target: Path, edit) -> Path:
    """A copy of the result file ``source`` at ``target`` with ``edit`` applied to its JSON."""
    data = json.loads(source.read_text())
    edit(data)
    target.parent.mkdir(parents=True, exist_ok=True)
    target.write_text(json.dumps(data))
    return target


def set_version(d: dict) -> None:
    d["model"]["version"] = d["configuration"]["model_version"] = "0"


def set_weights(d: dict) -> None:
    d["model"]["weights_digest"] = d["configuration"]["weights_digest"] = FAKE_DIGEST


def set_data(d: dict) -> None:
    d["data"]["digest"] = d["configuration"]["data_digest"] = "f" * 64


def old_format(d: dict) -> None:
    del d["configuration"], d["data"]["digest"], d["data"]["train"]


def old_format_old_version(d: dict) -> None:
    old_format(d)
    d["model"]["version"] = "0"


def test_constructed_files_are_classified_with_the_right_reason(swept, tmp_path):
    original = swept / "n0" / "mean-frame.json"
    recorded = json.loads(original.read_text())
    version, weights, data = (recorded["model"]["version"], recorded["model"]["weights_digest"],
                              recorded["data"]["digest"])
    assert recorded["configuration"]["data_digest"] == data and weights is not None
    zero = swept / "n0" / "zero.json"  # a model without a train split: old files still have it checked
    checker = Checker()
    verdicts = {name: checker.check(edited(source, tmp_path / f"{name}.json", edit)) for name, source, edit in
                [("version", original, set_version), ("weights", original, set_weights),
                 ("data", original, set_data), ("current", original, lambda d: None), ("old", zero, old_format),
                 ("old-fitted", original, old_format)]}
    assert {k: v.status for k, v in verdicts.items()} == {"version": STALE, "weights": STALE, "data": STALE,
                                                          "current": CURRENT, "old": UNVERIFIED,
                                                          "old-fitted": UNVERIFIED}
    assert verdicts["version"].reasons == (f"the model's version differs (was 0, now {version})",)
    assert verdicts["weights"].reasons == (f"the weights digest differs (was 000000000000, now {weights[:12]})",)
    assert verdicts["data"].reasons == (f"the data's content differs (was ffffffffffff, now {data[:12]})",)
    assert verdicts["current"].reasons == ()
    assert "records no data digest" in verdicts["old"].reasons[0]
    assert "does not record the train split" in verdicts["old-fitted"].reasons[0]
    # an old-format file still has its model checked: an old version is stale
    old_version = checker.check(edited(zero, tmp_path / "old-version.json", old_format_old_version))
    assert old_version.status == STALE and old_version.reasons == (
        f"the model's version differs (was 0, now {json.loads(zero.read_text())['model']['version']})",)


def test_a_vanished_data_folder_leaves_the_row_unverified(swept, tmp_path):
    def moved(d: dict) -> None:
        d["configuration"]["root"] = str(tmp_path / "gone" / "test")
    verdict = Checker().check(edited(swept / "n0" / "zero.json", tmp_path / "zero.json", moved))
    assert verdict.status == UNVERIFIED
    assert verdict.reasons == (f"its data folder {tmp_path / 'gone' / 'test'} no longer exists",)


def test_data_no_adapter_can_open_leaves_the_row_unverified(swept, tmp_path):
    def in_memory(d: dict) -> None:  # what evaluate() records for an in-memory split
        d["data"]["dataset"] = d["configuration"]["dataset"] = "handmade"
        d["data"]["root"] = d["configuration"]["root"] = None
    verdict = Checker().check(edited(swept / "n0" / "zero.json", tmp_path / "zero.json", in_memory))
    assert verdict.status == UNVERIFIED
    assert verdict.reasons[0].startswith("its data cannot be opened here: unknown dataset 'handmade'")


def stale_copy(swept: Path, tmp_path: Path) -> Path:
    """A results folder holding the sweep's four files, mean-frame at n=0 made stale (another weights digest)."""
    folder = tmp_path / "results"
    shutil.copytree(swept, folder / "dualtalk" / "test")
    stale = folder / "dualtalk" / "test" / "n0" / "mean-frame.json"
    edited(stale, stale, set_weights)
    return folder


def test_leaderboard_warns_about_the_stale_row_with_unchanged_tables(swept, tmp_path, capsys):
    folder = stale_copy(swept, tmp_path)
    code, out, err = run_cli(capsys, "leaderboard", folder, "--out", tmp_path / "tables", "--no-paper", "--latex")
    assert code == 0, out + err
    warnings = [line for line in err.splitlines() if line.startswith("warning: stale row")]
    assert len(warnings) == 1
    assert str(folder / "dualtalk" / "test" / "n0" / "mean-frame.json") in warnings[0]
    assert "the weights digest differs (was 000000000000" in warnings[0]
    assert "unverified" not in err
    for name, text in table_texts(long_table([folder], []), latex=True).items():
        assert (tmp_path / "tables" / name).read_text() == text, name


def test_sweep_stale_reruns_exactly_the_stale_row(swept, tmp_path, capsys):
    folder = stale_copy(swept, tmp_path)
    files = sorted(folder.rglob("*.json"))
    before = {p: p.read_bytes() for p in files}
    stale = folder / "dualtalk" / "test" / "n0" / "mean-frame.json"
    code, out, err = run_cli(capsys, "sweep", "--stale", "--out", folder)
    assert code == 0, out + err
    assert f"1 stale result file(s) of 4 under {folder} re-run" in out
    assert [p for p in files if p.read_bytes() != before[p]] == [stale]
    original, rerun = (json.loads((swept / "n0" / "mean-frame.json").read_text()), json.loads(stale.read_text()))
    assert rerun["configuration"] == original["configuration"]  # the recorded settings, the real weights
    assert rerun["per_clip"] == {"columns": [], "rows": []}  # the file had none (--no-per-clip)
    assert rerun["metrics"] == original["metrics"]
    assert Checker().check(stale).status == CURRENT


def test_sweep_stale_refuses_run_options(swept, capsys):
    code, out, err = run_cli(capsys, "sweep", "--stale", "--models", "zero", "--contexts", "1", "--out", swept)
    assert code == 2
    assert "--models, --contexts cannot be given with it" in err


def test_a_whole_clip_speech_normalisation_run_is_rechecked_with_that_setting(swept, tmp_path):
    """A result recorded with --speech-norm clip is re-run and compared under clip, never under the
    causal default (its configuration records the setting; the rebuilt protocol carries it)."""
    from dyadbench.results import load_result
    from dyadbench.staleness import recorded_run

    def clip(d: dict) -> None:
        d["protocol"]["speech_norm"] = d["configuration"]["speech_norm"] = "clip"

    source = next(swept.glob("n0/zero.json"))
    run = recorded_run(load_result(edited(source, tmp_path / "n0" / "zero@speech-clip.json", clip)))
    assert run.config.speech_norm == "clip"
    assert recorded_run(load_result(source)).config.speech_norm == "window"
