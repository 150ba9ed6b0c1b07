"""``sweep`` re-uses a stored run only when its file is a valid result of the very configuration requested.

Every case runs the real command line: one sweep writes ``mean-frame`` at n = 1 on 2 of the 3 test
dialogues of a DualTalk-layout root; the same sweep is then repeated after changing one thing.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from dyadbench.results import load_result
from tests.hostile_cli import dyadbench, write_dialogues, write_root
from tests.protocol_clips import isolated_cache  # noqa: F401


@pytest.fixture(scope="module")
def root(tmp_path_factory) -> Path:
    return write_root(tmp_path_factory.mktemp("dualtalk"), train=2, test=3)


@pytest.fixture()
def stored(root, tmp_path, capsys):
    """Run the sweep once; return (its arguments, the result file)."""
    args = ["sweep", "--models", "mean-frame", "--splits", "test", "--contexts", "1", "--out", tmp_path / "results"]
    code, output = dyadbench(capsys, *args, "--data", root, "--clips", "2")
    assert code == 0, output
    return args, tmp_path / "results" / "dualtalk" / "test" / "n1" / "mean-frame.json"


def rerun(capsys, args, *options) -> str:
    code, output = dyadbench(capsys, *args, *options)
    assert code == 0 and "Traceback" not in output, output
    return output


def test_an_identical_run_is_skipped_and_its_file_left_as_it_is(root, stored, capsys):
    args, path = stored
    before = path.read_bytes()
    output = rerun(capsys, args, "--data", root, "--clips", "2")
    assert f"skip {path} (same configuration" in output and "re-running" not in output
    assert path.read_bytes() == before


def test_other_clips_are_re_run(root, stored, capsys):
    args, path = stored
    output = rerun(capsys, args, "--data", root, "--clips", "3")
    assert f"re-running {path}: --clips differs (was 2, now 3)" in output and "skip" not in output
    assert load_result(path).data.clips == 3


def test_other_data_is_re_run(root, stored, tmp_path, capsys):
    args, path = stored
    other = tmp_path / "copy"
    shutil.copytree(root, other)
    output = rerun(capsys, args, "--data", other, "--clips", "2")  # same content, another folder
    assert f"re-running {path}: --data differs (was {(root / 'test').resolve()}, now {(other / 'test').resolve()})" \
        in output
    write_dialogues(other / "test", "test", 1, seed=7)  # the first dialogue's files now hold another dialogue
    output = rerun(capsys, args, "--data", other, "--clips", "2")
    assert f"re-running {path}: the data's content differs" in output
    assert load_result(path).configuration["root"] == str((other / "test").resolve())


def test_another_train_split_is_re_run(root, stored, tmp_path, capsys):
    args, path = stored
    train = write_dialogues(tmp_path / "other-train", "train", 1, seed=5)
    output = rerun(capsys, args, "--data", root, "--clips", "2", "--train", train)
    assert f"re-running {path}: the weights digest differs" in output  # of the fitted statistics
    assert "the train split differs" in output
    assert load_result(path).data.train["root"] == str(train.resolve())


@pytest.mark.parametrize("damage, reason", [
    (lambda text: text[: len(text) // 2], "result file unreadable: not readable JSON"),
    (lambda text: "", "result file unreadable: not readable JSON"),
    (lambda text: json.dumps({"schema": "something else"}), "result file unreadable: not a dyadbench eval result"),
    (lambda text: json.dumps({k: v for k, v in json.loads(text).items() if k != "metrics"}),
     "result file unreadable: field 'metrics' missing"),
    (lambda text: json.dumps({k: v for k, v in json.loads(text).items() if k != "configuration"}),
     "the result file records no configuration"),
])
def test_a_damaged_or_older_file_is_re_run(root, stored, capsys, damage, reason):
    args, path = stored
    path.write_text(damage(path.read_text()))
    output = rerun(capsys, args, "--data", root, "--clips", "2")
    assert f"re-running {path}: {reason}" in output and "skip" not in output
    assert load_result(path).configuration is not None  # a complete result again
    assert f"skip {path}" in rerun(capsys, args, "--data", root, "--clips", "2")


def test_force_re_runs_an_identical_run(root, stored, capsys):
    args, path = stored
    output = rerun(capsys, args, "--data", root, "--clips", "2", "--force")
    assert "skip" not in output and f"-> {path}" in output
