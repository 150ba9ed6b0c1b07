"""Train/test leakage and split naming: a model is never fitted on the clips it is scored on by accident.

Every case runs the real command line on a DualTalk-layout root holding train/ and test/ (2 short
dialogues each), or on one of its split folders given alone.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from dyadbench import provenance
from dyadbench.cli.splits import open_evaluated, train_opener
from dyadbench.datasets import dualtalk, gaze
from dyadbench.datasets.base import InMemorySource
from dyadbench.datasets.dualtalk_files import load_gt_npz
from dyadbench.errors import ConfigError
from dyadbench.results import EvalResult, load_result, result_files
from dyadbench.synth.gaze_writer import write_gaze_split
from tests.hostile_cli import dyadbench, error_line, write_dialogues, write_root
from tests.protocol_clips import isolated_cache, make_source  # noqa: F401

REPO = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def root(tmp_path_factory) -> Path:
    return write_root(tmp_path_factory.mktemp("dualtalk"), train=2, test=2)


def eval_args(model: str, out: Path, *options) -> list:
    return ["eval", "--model", model, "--context", "1", "--out", out, *options]


def test_a_split_folder_alone_has_no_train_split(root, tmp_path, capsys):
    code, output = dyadbench(capsys, *eval_args("nn-retrieval", tmp_path / "run", "--data", root / "test"))
    line = error_line(output)
    assert code == 2 and "nn-retrieval" in line and str(root / "test") in line and "--train DIR" in line
    assert not (tmp_path / "run").exists()
    code, output = dyadbench(capsys, *eval_args("zero", tmp_path / "zero", "--data", root / "test"))
    assert code == 0, output  # a model without a train split runs on the folder
    result = load_result(tmp_path / "zero" / "result.json")
    assert result.data.split == "test" and result.data.train is None and result.configuration["train"] is None


def _renamed_copy(folder: Path, target: Path) -> Path:
    """The same dialogues under other file names (clip ids ``other_0000i``)."""
    target.mkdir()
    for path in folder.iterdir():
        shutil.copy2(path, target / path.name.replace("synth_test", "other"))
    return target


@pytest.mark.parametrize("how", ["same folder", "renamed copy", "root's train split evaluated"])
def test_training_on_the_evaluated_clips_is_refused(root, tmp_path, capsys, how):
    if how == "same folder":
        train, options, shown = root / "test", ["--data", root / "test", "--train", root / "test"], "synth_test_00000"
    elif how == "renamed copy":
        train = _renamed_copy(root / "test", tmp_path / "copy")
        options, shown = ["--data", root / "test", "--train", train], "synth_test_00000 (= train other_00000)"
    else:
        train, options, shown = root / "train", ["--data", root, "--split", "train"], "synth_train_00000"
    evaluated = root / "train" if how == "root's train split evaluated" else root / "test"
    code, output = dyadbench(capsys, *eval_args("nn-retrieval", tmp_path / "run", *options))
    line = error_line(output)
    assert code == 2 and not (tmp_path / "run").exists()
    assert f"train split {train} holds 2 of the 2 clips evaluated from {evaluated}" in line
    assert shown in line and "--allow-train-overlap" in line


def test_forced_overlap_is_recorded_flagged_and_never_ranked(root, tmp_path, capsys):
    results = tmp_path / "results"
    forced = ["--data", root / "test", "--train", root / "test", "--allow-train-overlap"]
    code, output = dyadbench(capsys, *eval_args("nn-retrieval", tmp_path / "run", *forced))
    assert code == 0 and "[train-overlap=2: not ranked]" in output, output
    code, output = dyadbench(capsys, "sweep", "--models", "nn-retrieval", "--contexts", "1",
                             "--out", results / "forced", *forced)
    assert code == 0, output
    code, output = dyadbench(capsys, "sweep", "--models", "nn-retrieval,mean-frame", "--contexts", "1",
                             "--data", root, "--splits", "test", "--out", results / "clean")
    assert code == 0, output
    leak = load_result(results / "forced" / "dualtalk" / "test" / "n1" / "nn-retrieval.json")
    assert leak.flags() == "train-overlap=2" and leak.data.train["overlap"] == 2
    assert leak.notes[0].startswith("TRAIN OVERLAP") and str((root / "test").resolve()) in leak.notes[0]
    assert leak.metrics["mse_exp"] == 0.0 and abs(leak.metrics["fd_exp"]) < 1e-6  # what the flag guards against

    code, output = dyadbench(capsys, "leaderboard", results, "--out", tmp_path / "lb", "--no-paper")
    assert code == 0, output
    long = pd.read_csv(tmp_path / "lb" / "long.csv", keep_default_na=False)
    ours = long[long["model"] == "nn-retrieval"]
    assert sorted(set(ours["flags"])) == ["", "train-overlap=2"]
    oracle_level = long[(long["metric"] == "mse_exp") & (long["raw"].astype(float) < 1e-9)]
    assert len(oracle_level) == 1 and (oracle_level["flags"] == "train-overlap=2").all()
    wide = pd.read_csv(tmp_path / "lb" / "dualtalk_wide.csv", keep_default_na=False).set_index("flags")
    assert wide.loc["train-overlap=2", "rank"] == ""  # never ranked
    assert sorted(wide.loc[""]["rank"].astype(int)) == [1, 2]


def _frame_mean(folder: Path) -> np.ndarray:
    """Hand-computed mean over every frame of every participant of a DualTalk folder."""
    return np.concatenate([load_gt_npz(p) for p in sorted(folder.glob("*.npz"))]).astype(np.float64).mean(axis=0)


@pytest.mark.parametrize("train", ["split folder", "root"])
def test_train_dir_fits_on_a_separate_folder(root, tmp_path, capsys, train):
    given = root / "train" if train == "split folder" else root
    code, output = dyadbench(capsys, *eval_args("mean-frame", tmp_path / "run", "--data", root / "test",
                                                "--train", given, "--jobs", "2"))
    assert code == 0, output
    expected = _frame_mean(root / "train")
    for path in (tmp_path / "run" / "predictions").glob("*.npy"):
        np.testing.assert_allclose(np.load(path), np.broadcast_to(expected, np.load(path).shape), atol=1e-6)
    result = load_result(tmp_path / "run" / "result.json")
    assert result.data.train["root"] == str((root / "train").resolve())
    assert (result.data.train["split"], result.data.train["overlap"], result.flags()) == ("train", 0, "")
    assert result.configuration["train"]["digest"] == result.data.train["digest"] != result.data.digest


def test_a_split_folder_is_named_by_its_folder(root, tmp_path, capsys):
    code, output = dyadbench(capsys, *eval_args("zero", tmp_path / "run", "--data", root / "test", "--split", "ood"))
    line = error_line(output)
    assert code == 2 and f"{root / 'test'} is a single split folder ('test')" in line and "'ood'" in line
    assert not (tmp_path / "run").exists()
    code, output = dyadbench(capsys, "sweep", "--models", "zero", "--contexts", "1", "--data", root / "test",
                             "--splits", "ood,test", "--out", tmp_path / "results")
    assert code == 2 and "'ood'" in error_line(output)
    assert not list(tmp_path.rglob("*.json"))  # refused before any run: no "ood" row, no "test" row
    heldout = tmp_path / "heldout"
    shutil.copytree(root / "test", heldout)
    code, output = dyadbench(capsys, *eval_args("zero", tmp_path / "named", "--data", heldout))
    assert code == 0, output
    assert load_result(tmp_path / "named" / "result.json").data.split == "heldout"
    code, output = dyadbench(capsys, "sweep", "--models", "zero", "--contexts", "1", "--data", heldout,
                             "--out", tmp_path / "results")
    assert code == 0, output
    assert [p.relative_to(tmp_path / "results").as_posix() for p in result_files([tmp_path / "results"])] == [
        "dualtalk/heldout/n1/zero.json"]


def test_gaze_split_folders_follow_the_same_rules(tmp_path):
    write_gaze_split(tmp_path, split="test", clips=1, seed=3, duration_s=8)
    as_root, alone = gaze.open_split(tmp_path, None), gaze.open_split(tmp_path / "test", None)
    assert (as_root.split, as_root.single_split, alone.split, alone.single_split) == ("test", False, "test", True)
    with pytest.raises(ConfigError, match="single split folder"):
        gaze.open_split(tmp_path / "test", "ood")
    with pytest.raises(ConfigError, match="single split folder"):
        open_evaluated("gaze", tmp_path / "test", "ood")
    with pytest.raises(ConfigError, match="--train DIR"):
        train_opener("gaze", tmp_path / "test", alone, None, False)()


def test_clip_digests_are_cached_until_a_file_changes(root, tmp_path, monkeypatch):
    folder = shutil.copytree(root / "test", tmp_path / "test")
    first = provenance.clip_digests(dualtalk.open_split(folder, None))
    assert len(set(first.values())) == 2
    source = dualtalk.open_split(folder, None)
    monkeypatch.setattr(source, "participant_motions", lambda clip_id: pytest.fail("read a clip"))
    assert provenance.clip_digests(source) == first  # the second time nothing is read
    write_dialogues(folder, "test", 1, seed=9)  # synth_test_00000 now holds another dialogue
    again = provenance.clip_digests(dualtalk.open_split(folder, None))
    assert again["synth_test_00000"] != first["synth_test_00000"]
    assert again["synth_test_00001"] == first["synth_test_00001"]


class Generated(InMemorySource):
    """An in-memory split that says which generator made it (like the embedded corpus)."""

    def generated_by(self) -> dict:
        return {"generator": "test", "version": 1, "seed": 0, "split": self.split}


def test_splits_of_one_generator_are_compared_without_reading_clips():
    train, test = (make_source(2, split=s, seed=1) for s in ("train", "test"))  # same content, other names
    as_generated = {s.split: Generated(list(s), dataset="gen", split=s.split) for s in (train, test)}
    ids = test.clip_ids()
    assert provenance.shared_clips(train, test, ids) == [(c, c) for c in ids]  # by content
    assert provenance.shared_clips(as_generated["train"], as_generated["test"], ids) == []  # seeded by split
    assert provenance.shared_clips(as_generated["test"], as_generated["test"], ids) == [(c, c) for c in ids]
    assert provenance.split_digest(as_generated["test"]) != provenance.split_digest(as_generated["train"])


def test_every_committed_result_file_loads():
    files = result_files([REPO / "results"])
    assert files
    for path in files:
        result = load_result(path)
        assert result.flags() == "" and result.metrics, path
    old = result.to_dict()  # the oldest layout: none of the fields added for provenance
    for key in ("digest", "train"):
        old["data"].pop(key, None)
    old.pop("configuration", None)
    back = EvalResult.from_dict(old, "old.json")
    assert (back.data.digest, back.data.train, back.configuration) == (None, None, None)
