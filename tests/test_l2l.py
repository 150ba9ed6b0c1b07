"""Learning2Listen line: pairing rule, layout reading/validation, writer, suite values, scoring end to end."""

import json
from dataclasses import replace

import numpy as np
import pytest
from click.testing import CliRunner

from baselines.retrieval import build_nn_retrieval
from dyadbench.cli import cli
from dyadbench.datasets import l2l as layout
from dyadbench.errors import InputError
from dyadbench.metrics.l2l import L2LParams, keys, partner_keys, split_metrics
from dyadbench.motion import l2l_to_flame56
from dyadbench.protocol.config import ProtocolConfig
from dyadbench.protocol.interface import ModelOptions
from dyadbench.protocol.runner import evaluate, open_dataset_split
from dyadbench.protocol.streaming import stream_agent
from dyadbench.results import load_result
from dyadbench.scoring.l2l import score_arrays, score_paths
from dyadbench.scoring.report import ScoreItem
from dyadbench.synth.l2l_writer import resample, write_l2l_split
from tests.l2l_root import l2l_train_test  # noqa: F401


def _write_host(folder, n0, n1, seed=0):
    """Hand-made arrays: person p's faces carry the value 10 * p + kind code in every motion dim."""
    rng = np.random.default_rng(seed)
    folder.mkdir(parents=True)
    counts = {0: n0, 1: n1}  # windows where person p listens
    for p in (0, 1):
        talker_n = counts[1 - p]
        np.save(folder / layout.array_name(p, "list_faces"), np.full((counts[p], 64, 184), 10.0 * p + 1, np.float32))
        np.save(folder / layout.array_name(p, "speak_faces"), np.full((talker_n, 64, 184), 10.0 * p + 2, np.float32))
        np.save(folder / layout.array_name(p, "speak_audio"), rng.random((talker_n, 256, 128)).astype(np.float32))
        np.save(folder / layout.array_name(p, "speak_files"), np.full((talker_n, 64, 3), "v", dtype="<U8"))


def test_host_is_the_listener_with_fallon_swapped(tmp_path):
    _write_host(tmp_path / "conan" / "test", 3, 5)
    _write_host(tmp_path / "fallon" / "test", 3, 5)
    stems, listener, speaker = layout.ground_truth(tmp_path, "test")
    assert len(stems) == 3 + 5
    assert stems[0] == "conan_test_00000_listener" and stems[3] == "fallon_test_00000_listener"
    assert (listener[:3] == 1).all() and (speaker[:3] == 12).all()  # conan: p0 listens, p1 speaks
    assert (listener[3:] == 11).all() and (speaker[3:] == 2).all()  # fallon: p1 listens, p0 speaks
    assert layout.listener_person("fallon") == 1 and layout.listener_person("kimmel") == 0


def test_motion_is_reordered_to_flame56(tmp_path):
    folder = tmp_path / "trevor" / "test"
    _write_host(folder, 2, 2)
    faces = np.zeros((2, 64, 184), np.float32)
    faces[..., 50:53] = 0.1  # L2L rotation
    faces[..., 53:56] = 0.2  # L2L jaw
    np.save(folder / layout.array_name(0, "list_faces"), faces)
    clip = layout.open_split(tmp_path, "test").load("trevor_test_00000")
    motion = clip.participants[0].motion
    assert clip.participants[0].name == "listener" and clip.fps == 30.0
    np.testing.assert_array_equal(motion, l2l_to_flame56(faces[0]))
    assert np.allclose(motion[:, 50:53], 0.2) and np.allclose(motion[:, 53:56], 0.1)  # [exp | jaw | rotation]
    assert clip.participant("speaker").speech_features.shape == (256, 128)
    assert clip.participant("speaker").feature_rows_per_frame == 4
    assert clip.participant("listener").speech_features is None
    assert clip.agent_ids() == [f"{clip.clip_id}_listener"]


def test_validation_reports_mismatched_pairs(tmp_path):
    _write_host(tmp_path / "kimmel" / "test", 3, 4)
    np.save(tmp_path / "kimmel" / "test" / layout.array_name(1, "speak_faces"), np.zeros((2, 64, 184), np.float32))
    (tmp_path / "kimmel" / "test" / layout.array_name(0, "speak_files")).unlink()  # not paired on kimmel
    report = layout.validate_folder(tmp_path, progress=False)
    text = "\n".join(report.errors)
    assert "disagree on the number of windows" in text and "p0_speak_files_clean_deca.npy: missing" in text
    with pytest.raises(InputError, match="splits train, test"):
        layout.open_split(tmp_path, "val")


def test_resample_keeps_linear_motion_linear():
    x = np.arange(26, dtype=float)[:, None] * 0.5  # 25 fps ramp over 1 s
    y = resample(x, 25.0, 30.0)
    assert len(y) == 31
    np.testing.assert_allclose(y[:, 0], np.arange(31) * 25 / 30 * 0.5)


@pytest.fixture(scope="module")
def l2l_root(tmp_path_factory):
    root = tmp_path_factory.mktemp("l2l")
    write_l2l_split(root, split="test", clips=2, seed=0, progress=False)
    return root


def test_written_split(l2l_root):
    assert layout.validate_folder(l2l_root, progress=False).errors == []
    info = layout.folder_info(l2l_root, progress=False)["hosts"]["synth"]
    stems, listener, speaker = layout.ground_truth(l2l_root, "test")
    assert info["test"]["windows"] == len(stems) > 0 and listener.shape == (len(stems), 64, 56)
    assert not np.array_equal(listener, speaker)
    marker = json.loads((l2l_root / "synth" / "test" / "synthetic.json").read_text())
    assert marker["windows"]["p0_listening"] == len(stems)


def _sequences(seed, n=6, t=64):
    rng = np.random.default_rng(seed)
    gts = [rng.normal(size=(t, 56)) for _ in range(n)]
    speakers = [0.5 * g + rng.normal(size=(t, 56)) for g in gts]
    return gts, speakers


def test_ground_truth_as_prediction():
    gts, speakers = _sequences(0)
    metrics, per_sequence = split_metrics(gts, gts, speakers)
    for c in ("exp", "pose", "jaw"):
        assert metrics[f"l2_{c}"] == 0.0 and metrics[f"rpcc_{c}"] == 0.0
        assert metrics[f"var_{c}"] == metrics[f"var_gt_{c}"]
        assert metrics[f"si_{c}"] == metrics[f"si_gt_{c}"]
        assert metrics[f"fd_{c}"] == pytest.approx(0.0, abs=1e-6)
    assert list(metrics) == keys()
    assert len(per_sequence) == 6


CENTRES = 10.0 * (np.arange(256) % 4)[:, None] * np.ones((1, 56))


def _clustered(n=4, seed=1):
    """``n`` sequences of 256 frames near four centres 10 j (1, ..., 1), j = frame mod 4, unit noise with
    mean 0 in every sequence and dim (so every sequence has the same mean)."""
    noise = [x - x.mean(axis=0) for x in np.random.default_rng(seed).normal(size=(n, *CENTRES.shape))]
    return [CENTRES + x for x in noise]


DIMS = {"exp": 50, "pose": 3, "jaw": 3}


def test_suite_values_by_hand_for_shifted_predictions():
    # sequence i shifted by c_i in every dim: squared error c_i^2 per value, so L2 = mean c_i^2 = 0.075
    # (equal lengths); equal covariances leave FD = P-FD = dims * c_i^2 per sequence, averaged: dims * 0.075;
    # equal sequence means: the pooled variance gains the shifts' variance 0.075 - 0.25^2 = 0.0125; shifts keep
    # every frame's cluster, so SI = SI-GT = -log2(1/4 + 1e-6) (four equally filled clusters, k = 4)
    gts, speakers = _clustered(), _clustered(seed=2)
    preds = [g + c for g, c in zip(gts, (0.1, 0.2, 0.3, 0.4))]
    params = L2LParams(si_k={"exp": 4, "pose": 4, "jaw": 4})
    metrics, per_sequence = split_metrics(preds, gts, speakers, params)
    four_clusters = -np.log2(0.25 + 1e-6)
    for c, dims in DIMS.items():
        assert metrics[f"l2_{c}"] == pytest.approx(0.075, rel=1e-9)
        assert metrics[f"fd_{c}"] == pytest.approx(dims * 0.075, rel=1e-6)
        assert metrics[f"pfd_{c}"] == pytest.approx(dims * 0.075, rel=1e-6)
        assert [s[f"fd_{c}"] for s in per_sequence] == pytest.approx([dims * x * x for x in (0.1, 0.2, 0.3, 0.4)],
                                                                     rel=1e-6)
        assert metrics[f"var_{c}"] - metrics[f"var_gt_{c}"] == pytest.approx(0.0125, rel=1e-9)
        assert metrics[f"si_{c}"] == pytest.approx(four_clusters, rel=1e-12)
        assert metrics[f"si_gt_{c}"] == pytest.approx(four_clusters, rel=1e-12)


def test_suite_values_by_hand_for_centred_and_mirrored_predictions():
    # the prediction keeps the noise and drops the centres: one occupied cluster, SI = -log2(1 + 1e-6); the
    # ground truth's variance per dim adds the centres' 0, 10, 20, 30 equally weighted: 125
    gts, speakers = _clustered(), _clustered(seed=2)
    centred = [g - CENTRES for g in gts]
    metrics, _ = split_metrics(centred, gts, speakers, L2LParams(si_k={"exp": 4, "pose": 4, "jaw": 4}))
    for c in DIMS:
        assert metrics[f"si_{c}"] == pytest.approx(-np.log2(1 + 1e-6), rel=1e-12)
        assert metrics[f"var_gt_{c}"] - metrics[f"var_{c}"] == pytest.approx(125.0, rel=0.01)
    # p = 1 - 2 g: four times the variance, and the correlation with the speaker flips: rPCC = |r - (-r)| = 2 r,
    # r = corr(g, a) of the flattened pooled frames (numpy's corrcoef)
    metrics, _ = split_metrics([1 - 2 * g for g in gts], gts, speakers)
    for c, cols in (("exp", slice(0, 50)), ("jaw", slice(50, 53)), ("pose", slice(53, 56))):
        r = np.corrcoef(np.concatenate(gts)[:, cols].ravel(), np.concatenate(speakers)[:, cols].ravel())[0, 1]
        assert r > 0.9 and metrics[f"rpcc_{c}"] == pytest.approx(2 * r, rel=1e-9)
        assert metrics[f"var_{c}"] == pytest.approx(4 * metrics[f"var_gt_{c}"], rel=1e-12)


def test_score_arrays_excludes_nan_and_scores_without_the_speaker():
    gts, speakers = _sequences(3, n=4)
    preds = [g.copy() for g in gts]
    preds[1][3, 4] = np.nan
    report = score_arrays([ScoreItem(f"w{i}", p, g, a) for i, (p, g, a) in enumerate(zip(preds, gts, speakers))])
    assert report.n_scored == 3 and report.excluded[0]["clip"] == "w1"
    assert report.config["parameters"]["si_k"] == {"exp": 15, "pose": 9, "jaw": 9}
    alone = score_arrays([ScoreItem("w0", gts[0], gts[0])])  # no speaker at all: P-FD and rPCC are NaN
    assert alone.metrics["l2_exp"] == 0.0 and np.isnan(alone.metrics["pfd_exp"]) and np.isnan(alone.metrics["rpcc_jaw"])
    assert alone.coverage["not_computable"] == [{"clip": "w0", "metrics": partner_keys(),
                                                 "reason": "no speaker motion given (partner=None)"}]
    assert alone.uncertainty["rpcc_exp"] == {"unavailable": "no scored clip has the speaker's motion"}
    assert "P-FD, rPCC not computable for 1 of 1 clips" in " ".join(alone.notes)


def test_without_a_speaker_a_window_is_left_out_of_pfd_and_rpcc_only():
    # shifts c_i as in the hand-derived case above; sequence 3 (c = 0.4) has no speaker: L2 and FD keep it
    # (L2 = mean c^2 = 0.075), P-FD = dims * mean c^2 over the other three = dims * 0.14 / 3; with p = 1 - 2 g
    # rPCC = 2 r, r = corr(g, a) of the three sequences that have a speaker (numpy's corrcoef)
    gts, speakers = _clustered(), _clustered(seed=2)
    without = speakers[:3] + [None]
    metrics, per_sequence = split_metrics([g + c for g, c in zip(gts, (0.1, 0.2, 0.3, 0.4))], gts, without)
    assert np.isnan(per_sequence[3]["pfd_exp"]) and per_sequence[3]["fd_exp"] == pytest.approx(50 * 0.16, rel=1e-6)
    for c, dims in DIMS.items():
        assert metrics[f"l2_{c}"] == pytest.approx(0.075, rel=1e-9)
        assert metrics[f"fd_{c}"] == pytest.approx(dims * 0.075, rel=1e-6)
        assert metrics[f"pfd_{c}"] == pytest.approx(dims * 0.14 / 3, rel=1e-6)
    metrics, _ = split_metrics([1 - 2 * g for g in gts], gts, without)
    for c, cols in (("exp", slice(0, 50)), ("jaw", slice(50, 53)), ("pose", slice(53, 56))):
        r = np.corrcoef(np.concatenate(gts[:3])[:, cols].ravel(), np.concatenate(speakers[:3])[:, cols].ravel())[0, 1]
        assert metrics[f"rpcc_{c}"] == pytest.approx(2 * r, rel=1e-9)
    assert partner_keys() == [f"{m}_{c}" for m in ("pfd", "rpcc") for c in ("exp", "pose", "jaw")]


def _write_random_host(folder, n, seed):
    """A host split with ``n`` windows of random motion for both persons (every array present)."""
    rng = np.random.default_rng(seed)
    folder.mkdir(parents=True)
    for p in (0, 1):
        for kind in ("list_faces", "speak_faces"):
            np.save(folder / layout.array_name(p, kind), rng.normal(size=(n, 64, 184)).astype(np.float32))
        np.save(folder / layout.array_name(p, "speak_audio"), rng.random((n, 256, 128)).astype(np.float32))
        np.save(folder / layout.array_name(p, "speak_files"), np.full((n, 64, 3), "v", dtype="<U8"))


def test_a_root_missing_one_speakers_file_scores_with_partner_metrics_not_computable(tmp_path):
    root = tmp_path / "l2l"
    _write_random_host(root / "conan" / "test", 3, seed=0)
    _write_random_host(root / "kimmel" / "test", 2, seed=1)
    gone = root / "kimmel" / "test" / layout.array_name(1, "speak_faces")  # kimmel listens (p0), p1 speaks
    gone.unlink()
    shifts = {"conan_test_00000": 0.1, "conan_test_00001": 0.2, "conan_test_00002": 0.3,
              "kimmel_test_00000": 0.4, "kimmel_test_00001": 0.5}
    preds = tmp_path / "preds"
    preds.mkdir()
    for host, n in (("conan", 3), ("kimmel", 2)):
        faces = np.load(root / host / "test" / layout.array_name(0, "list_faces"))
        for i in range(n):
            clip = f"{host}_test_{i:05d}"
            np.save(preds / f"{clip}_listener.npy", l2l_to_flame56(faces[i]).astype(np.float64) + shifts[clip])
    result = CliRunner().invoke(cli, ["score", str(preds), "--suite", "l2l", "--gt", str(root), "--strict",
                                      "--out", str(tmp_path / "r")])
    assert result.exit_code == 0, result.output
    assert "scored 5 of 5; 2 of them without pfd, rpcc (not computable" in result.output
    assert "P-FD, rPCC not computable for 2 of 5 clips" in result.output
    saved = load_result(tmp_path / "r" / "result.json")
    reason = f"speaker motion {gone} not found"
    assert saved.coverage["not_computable"] == [
        {"clip": f"kimmel_test_{i:05d}_listener", "metrics": partner_keys(), "reason": reason} for i in range(2)]
    rows = {r["clip"]: r for r in saved.per_clip}
    # a shift c leaves covariances alone: FD = P-FD = dims * c^2 per window; L2 = mean c^2 over all windows
    squares = np.square(list(shifts.values()))
    for c, dims in DIMS.items():
        assert saved.metrics[f"l2_{c}"] == pytest.approx(squares.mean(), rel=1e-6)
        assert saved.metrics[f"fd_{c}"] == pytest.approx(dims * squares.mean(), rel=1e-4)
        assert saved.metrics[f"pfd_{c}"] == pytest.approx(dims * squares[:3].mean(), rel=1e-4)
        assert np.isnan(rows["kimmel_test_00001_listener"][f"pfd_{c}"])
        assert rows["kimmel_test_00001_listener"][f"fd_{c}"] == pytest.approx(dims * 0.25, rel=1e-4)
        assert np.isfinite(saved.metrics[f"rpcc_{c}"])


def test_cli_end_to_end(tmp_path):
    runner = CliRunner()
    root = tmp_path / "l2l"
    result = runner.invoke(cli, ["data", "synth", "--layout", "l2l", "--out", str(root), "--split", "test",
                                 "--clips", "1"])
    assert result.exit_code == 0, result.output
    stems, listener, _ = layout.ground_truth(root, "test")
    preds = tmp_path / "preds"
    preds.mkdir()
    for stem, motion in zip(stems[:-1], listener[:-1]):
        np.save(preds / f"{stem}.npy", motion)
    result = runner.invoke(cli, ["score", str(preds), "--suite", "l2l", "--gt", str(root), "--out", str(tmp_path / "r")])
    assert result.exit_code == 0, result.output
    saved = json.loads((tmp_path / "r" / "result.json").read_text())
    assert saved["metrics"]["l2_exp"] == 0.0 and saved["metrics"]["rpcc_pose"] == 0.0
    assert saved["coverage"]["missing"] == [stems[-1]]
    np.savez(tmp_path / "wrong.npz", other=listener[0])
    with pytest.raises(InputError, match="named like no ground-truth item"):
        score_paths(tmp_path / "wrong.npz", root)


@pytest.mark.parametrize("model", ["mean-frame", "random", "mime", "lagged-mirror", "nn-retrieval", "oracle"])
def test_baselines_stream_the_listener_and_are_scored_with_the_l2l_suite(l2l_train_test, model, monkeypatch,
                                                                         tmp_path):
    monkeypatch.setenv("DYADBENCH_CACHE", str(tmp_path / "cache"))
    train = lambda: open_dataset_split("l2l", l2l_train_test, "train")  # noqa: E731
    result = evaluate(model, layout.open_split(l2l_train_test, "test"), ProtocolConfig(context=1),
                      options=ModelOptions(train_split=train), progress=False)
    stems = layout.ground_truth(l2l_train_test, "test")[0]
    assert result.suite == "l2l" and sorted(r["clip"] for r in result.per_clip) == stems
    assert np.isfinite(result.metrics["fd_exp"]) and np.isfinite(result.metrics["pfd_pose"])
    if model == "oracle":
        assert result.metrics["l2_exp"] == 0.0


def test_retrieval_index_of_shipped_features_refuses_a_waveform_partner(l2l_train_test, monkeypatch, tmp_path):
    monkeypatch.setenv("DYADBENCH_CACHE", str(tmp_path / "cache"))
    model = build_nn_retrieval(ModelOptions(train_split=lambda: open_dataset_split("l2l", l2l_train_test, "train"),
                                            extra={"turn_seconds": 1.0}))
    clip = layout.open_split(l2l_train_test, "test").load("synth_test_00000")
    listener, speaker = clip.participants
    waveform = replace(speaker, audio=np.ones(int(64 / 30 * 16000), np.float32), speech_features=None)
    with pytest.raises(InputError, match="features-128; this stream's partner has log-mel") as err:
        stream_agent(model, replace(clip, participants=(listener, waveform)), "listener", ProtocolConfig())
    assert "synth_test_00000_speaker" in str(err.value)
