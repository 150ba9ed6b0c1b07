"""REACT layout: mirrored order, reading, validation, the synthetic writer, scoring files end to end."""

import json

import numpy as np
import pytest
from click.testing import CliRunner

from dyadbench.cli import cli
from dyadbench.datasets.react import ReactSplit, folder_info, mirrored, open_split, read_emotion, validate_folder
from dyadbench.errors import InputError
from dyadbench.metrics import react
from dyadbench.scoring.react import load_predictions, score_arrays, score_paths
from dyadbench.scoring.report import ScoreItem
from dyadbench.synth.react_writer import emotion_features, neighbour_matrix, write_react_split


@pytest.fixture(scope="module")
def react_root(tmp_path_factory):
    root = tmp_path_factory.mktemp("react")
    write_react_split(root, split="val", clips=3, seed=0, progress=False)
    return root


def test_mirrored_order():
    pairs = [("A/s1", "A/l1"), ("B/s2", "B/l2")]
    assert mirrored(pairs) == [("A/s1", "A/l1"), ("B/s2", "B/l2"), ("A/l1", "A/s1"), ("B/l2", "B/s2")]


def test_written_split_reads_back(react_root):
    data = ReactSplit.open(react_root, "val")
    assert len(data.pairs) == 3 and len(data.samples) == 6
    speaker, listener = data.samples[4]  # k = M + 1: columns swapped
    assert (listener, speaker) == data.pairs[1]
    lst, spk = data.ground_truth(750)
    assert lst.shape == spk.shape == (6, 750, 25) and lst.dtype == np.float32
    np.testing.assert_array_equal(lst[0], spk[3])  # the listener of sample k is the speaker of sample k + M
    s = data.neighbours()
    assert s.shape == (6, 6) and (s.sum(axis=1) >= 1).all() and (np.diag(s) == 1).all()
    assert validate_folder(react_root, progress=False).ok
    info = folder_info(react_root, progress=False)["splits"]["val"]
    assert info["dialogues"] == 3 and info["samples"] == 6 and info["frames"] == {"min": 751, "max": 751}
    clip = open_split(react_root, "val").load("val_00000")
    assert clip.layout == "react25" and clip.participants[0].motion.shape == (751, 25)


def test_emotion_csv_round_trips_float32_exactly(react_root):
    data = ReactSplit.open(react_root, "val")
    marker = json.loads((react_root / "val" / "synthetic.json").read_text())
    assert marker["emotion_mapping"]["au_threshold"] == 0.4
    values = read_emotion(data.emotion_path(data.people[0]))
    assert values.shape == (751, 25)
    assert set(np.unique(values[:, :15])) <= {0.0, 1.0}
    np.testing.assert_allclose(values[:, 17:].sum(axis=1), 1.0, atol=1e-6)
    assert np.abs(values[:, 15:17]).max() <= 1.0


def test_emotion_mapping_and_neighbours_are_deterministic():
    motion = np.random.default_rng(0).normal(size=(100, 56)).astype(np.float32)
    a, b = emotion_features(motion), emotion_features(motion.copy())
    np.testing.assert_array_equal(a, b)
    listener = np.random.default_rng(1).random((40, 30, 25))
    s = neighbour_matrix(listener)
    assert (s.sum(axis=1) == 3).all() and (np.diag(s) == 1).all()


def test_validation_names_broken_files(tmp_path):
    write_react_split(tmp_path, split="val", clips=2, seed=0, progress=False)
    data = ReactSplit.open(tmp_path, "val")
    data.emotion_path(data.people[1]).unlink()
    s = np.load(tmp_path / "neighbour_emotion_val.npy")
    s[2] = 0
    np.save(tmp_path / "neighbour_emotion_val.npy", s)
    report = validate_folder(tmp_path, progress=False)
    assert not report.ok
    text = "\n".join(report.errors)
    assert "1.csv: file not found" in text and data.people[1] in text
    assert "row 2" in text and "no neighbour" in text


def _predictions(root, seed=0):
    data = ReactSplit.open(root, "val")
    rng = np.random.default_rng(seed)
    return data, rng.random((len(data.samples), 10, 750, 25)).astype(np.float32)


def test_prediction_forms_score_identically(react_root, tmp_path):
    data, p = _predictions(react_root)
    np.savez(tmp_path / "stacked.npz", predictions=p)
    np.savez(tmp_path / "keyed.npz", **{spk: p[k] for k, (spk, _) in enumerate(data.samples)})
    folder = tmp_path / "folder"
    for k, (spk, _) in enumerate(data.samples):
        (folder / spk).parent.mkdir(parents=True, exist_ok=True)
        np.save(folder / f"{spk}.npy", np.concatenate([p[k], p[k][:, :1]], axis=1))  # 751 frames: cut to 750
    speakers = [s for s, _ in data.samples]
    for path in (tmp_path / "stacked.npz", tmp_path / "keyed.npz", folder):
        found = load_predictions(path, speakers, 10, 750)
        np.testing.assert_array_equal(np.stack([found.arrays[s] for s in speakers]), p)
    reports = [score_paths(tmp_path / "keyed.npz", react_root, split="val")]
    lst, spk = data.ground_truth(750)
    assert reports[0].metrics == react.score(p, lst, spk, data.neighbours())
    assert [row["clip"] for row in reports[0].per_item] == [s for s, _ in data.samples]
    assert "FRRea not computed" in " ".join(reports[0].notes)
    corr = np.mean([row["FRCorr"] for row in reports[0].per_item])
    assert corr == pytest.approx(reports[0].metrics["FRCorr"], rel=1e-12)


def test_prediction_file_errors(react_root, tmp_path):
    data, p = _predictions(react_root)
    np.savez(tmp_path / "r3.npz", predictions=p[:, :3])
    with pytest.raises(InputError, match=r"\(6, 10, T, 25\)"):
        score_paths(tmp_path / "r3.npz", react_root, split="val")
    keyed = {spk: p[k] for k, (spk, _) in enumerate(data.samples)}
    missing = data.samples[2][0]
    del keyed[missing]
    np.savez(tmp_path / "missing.npz", **keyed)
    report = score_paths(tmp_path / "missing.npz", react_root, split="val")  # the policy: listed, not fatal
    assert report.coverage["missing"] == [missing] and report.n_scored == 5 and not report.complete
    short = p[:, :, :700]
    np.savez(tmp_path / "short.npz", predictions=short)
    with pytest.raises(InputError, match="700 frames"):
        score_paths(tmp_path / "short.npz", react_root, split="val")
    with pytest.raises(InputError, match="val and test"):
        score_paths(tmp_path / "short.npz", react_root, split="train")


def test_score_arrays_defaults_to_own_listener():
    rng = np.random.default_rng(3)
    items = [ScoreItem(f"s{k}", rng.random((2, 60, 25)), rng.random((60, 25)), rng.random((60, 25)))
             for k in range(3)]
    report = score_arrays(items)
    assert "only appropriate reaction" in report.notes[0]
    assert set(report.metrics) == set(react.KEYS)


def test_cli_end_to_end(tmp_path):
    runner = CliRunner()
    root = tmp_path / "react"
    result = runner.invoke(cli, ["data", "synth", "--layout", "react", "--out", str(root), "--split", "val",
                                 "--clips", "2"])
    assert result.exit_code == 0, result.output
    data = ReactSplit.open(root, "val")
    p = np.broadcast_to(np.full(25, 0.5, np.float32), (len(data.samples), 10, 750, 25))
    np.savez(tmp_path / "meanfr.npz", predictions=p)
    result = runner.invoke(cli, ["score", str(tmp_path / "meanfr.npz"), "--suite", "react", "--gt", str(root),
                                 "--split", "val", "--out", str(tmp_path / "res")])
    assert result.exit_code == 0, result.output
    metrics = json.loads((tmp_path / "res" / "result.json").read_text())["metrics"]
    assert metrics["FRCorr"] == 0.0 and metrics["FRSyn"] == 49.0 and metrics["FRDiv"] == 0.0
