"""`dyadbench score` with the DualTalk suite, end to end on small generated files."""

import json
import math
import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from threadpoolctl import threadpool_limits

from dyadbench.cli import main
from dyadbench.datasets.dualtalk_files import load_gt_npz, write_gt_npz
from dyadbench.errors import InputError
from dyadbench.metrics.dualtalk import KEYS, PARTNER_KEYS, SCALE, clip_metrics
from dyadbench.results import load_result
from dyadbench.scoring.dualtalk import partner_stem, score_arrays, score_paths
from dyadbench.scoring.report import ScoreItem
from dyadbench.seeding import derive_seed

T = 110
CLIPS = ("dlgA", "dlgB", "dlgC")
DEMO = Path("/work/shared/data/dualtalk-demo")


def _smooth(rng, t=T):
    steps = rng.normal(size=(t, 56)) * np.r_[np.full(50, 0.1), np.full(6, 0.01)]
    return np.cumsum(steps, axis=0) + rng.normal(size=56) * 0.3


@pytest.fixture()
def dataset(tmp_path):
    """GT split folder (with wavs that must be ignored) and a prediction folder for every agent."""
    rng = np.random.default_rng(0)
    gt, pred = tmp_path / "gt", tmp_path / "pred"
    gt.mkdir()
    pred.mkdir()
    for clip in CLIPS:
        for k in (1, 2):
            stem = f"{clip}_speaker{k}"
            motion = _smooth(rng)
            write_gt_npz(gt / f"{stem}.npz", motion, extra={"cam": np.zeros((T, 3), np.float32)})
            (gt / f"{stem}.wav").write_bytes(b"RIFF")
            np.save(pred / f"{stem}.npy", (motion + 0.2 * _smooth(rng)).astype(np.float32))
    return gt, pred


def run(capsys, *args):
    """Run the real entry point; return (exit code, stdout, stderr)."""
    try:
        main(["score", *map(str, args)])
        code = 0
    except SystemExit as exc:
        code = exc.code
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def _results(out):
    return json.loads((out / "result.json").read_text()), pd.read_csv(out / "per_clip.csv")


def test_outputs_and_table(dataset, tmp_path, capsys):
    gt, pred = dataset
    code, out, err = run(capsys, pred, "--gt", gt, "--out", tmp_path / "res")
    assert code == 0, err
    assert "scored 6 of 6" in out
    assert out.splitlines()[1].split()[:5] == ["FD", "exp", "FD", "jaw", "x1e3"]
    order = ["FD exp", "P-FD exp", "MSE exp x10", "SID exp", "rPCC exp x1e2", "SID-gtfit exp", "STS exp"]
    assert [out.index(h) for h in order] == sorted(out.index(h) for h in order)
    assert max(len(line) for line in out.splitlines()[1:-1]) <= 100
    results, frame = _results(tmp_path / "res")
    assert results["schema"] == "dyadbench.eval-result/1"
    assert load_result(tmp_path / "res" / "result.json").external
    assert results["protocol"]["name"] == "external predictions" and results["protocol"]["context"] is None
    assert results["model"]["name"] == "pred" and results["predictions"] == str(pred)  # PRED's name by default
    assert list(results["metrics"]) == list(KEYS)
    assert results["data"]["items"] == 6 and results["data"]["clips"] == 3 and results["coverage"]["expected"] == 6
    assert list(frame.columns) == ["clip", *KEYS]
    assert list(frame["clip"]) == [f"{c}_speaker{k}" for c in CLIPS for k in (1, 2)]
    # plain mean over clips, and publication scaling
    for key in KEYS:
        assert results["metrics"][key] == pytest.approx(frame[key].mean(), rel=1e-9)
        assert results["scaled"][key] == pytest.approx(results["metrics"][key] * SCALE[key])
    config = results["model"]["config"]
    assert results["protocol"]["seed"] == 0 and "derive_seed(seed, stem)" in config["diversity_seed_rule"]


def test_per_clip_values_are_the_metric_functions(dataset):
    gt, pred = dataset
    report = score_paths(pred, gt, seed=4)
    stem = "dlgB_speaker2"
    with threadpool_limits(limits=1):  # as the scorer runs; multi-threaded BLAS differs by ~1e-12
        expected = clip_metrics(np.load(pred / f"{stem}.npy").astype(np.float64),
                                load_gt_npz(gt / f"{stem}.npz"), load_gt_npz(gt / "dlgB_speaker1.npz"),
                                seed=derive_seed(4, stem))
    row = next(r for r in report.per_item if r["clip"] == stem)
    assert {k: row[k] for k in KEYS} == expected


def test_npz_input_and_arrays_and_jobs_give_identical_results(dataset, tmp_path, capsys):
    gt, pred = dataset
    archive = tmp_path / "preds.npz"
    np.savez(archive, **{f.stem: np.load(f) for f in sorted(pred.glob("*.npy"))})
    assert run(capsys, pred, "--gt", gt, "--out", tmp_path / "a")[0] == 0
    assert run(capsys, archive, "--gt", gt, "--out", tmp_path / "b", "--jobs", "2")[0] == 0
    assert (tmp_path / "a" / "per_clip.csv").read_text() == (tmp_path / "b" / "per_clip.csv").read_text()
    assert _results(tmp_path / "a")[0]["metrics"] == _results(tmp_path / "b")[0]["metrics"]
    items = []
    for f in sorted(pred.glob("*.npy")):
        clip, k = f.stem.rsplit("_speaker", 1)
        items.append(ScoreItem(f.stem, np.load(f), load_gt_npz(gt / f"{f.stem}.npz"),
                               load_gt_npz(gt / f"{clip}_speaker{3 - int(k)}.npz")))
    in_memory = score_arrays(items)
    assert in_memory.metrics == _results(tmp_path / "a")[0]["metrics"]


def test_nan_prediction_is_excluded_and_listed(dataset, tmp_path, capsys):
    gt, pred = dataset
    bad = np.load(pred / "dlgA_speaker2.npy")
    bad[5, 7] = np.nan
    np.save(pred / "dlgA_speaker2.npy", bad)
    code, out, _ = run(capsys, pred, "--gt", gt, "--out", tmp_path / "res")
    assert code == 0
    assert "scored 5 of 6" in out and "dlgA_speaker2 (1 NaN/inf values" in out
    results, frame = _results(tmp_path / "res")
    reason = f"1 NaN/inf values (first at index (5, 7)) in {pred / 'dlgA_speaker2.npy'}"
    assert results["excluded"] == [{"clip": "dlgA_speaker2", "reason": reason}]
    assert "dlgA_speaker2" not in set(frame["clip"])
    assert all(math.isfinite(v) for v in results["metrics"].values())
    code, _, err = run(capsys, pred, "--gt", gt, "--strict")
    assert code == 1 and "--strict" in err


def test_missing_prediction_is_reported_and_strict_fails(dataset, capsys):
    gt, pred = dataset
    (pred / "dlgC_speaker1.npy").unlink()
    code, out, _ = run(capsys, pred, "--gt", gt)
    assert code == 0 and "scored 5 of 6; missing: dlgC_speaker1" in out
    assert run(capsys, pred, "--gt", gt, "--strict")[0] == 1


def test_complete_set_passes_strict(dataset, capsys):
    gt, pred = dataset
    assert run(capsys, pred, "--gt", gt, "--strict")[0] == 0


@pytest.mark.parametrize("missing", ["dlgB_speaker1", "dlgB_speaker2"])
def test_missing_partner_file_is_named_and_partner_metrics_not_computable(dataset, tmp_path, capsys, missing):
    gt, pred = dataset
    (gt / f"{missing}.npz").unlink()
    code, out, err = run(capsys, pred, "--gt", gt, "--out", tmp_path / "res")
    assert code == 0, err
    assert "scored 5 of 5" in out and "1 of them without pfd, rpcc" in out
    assert "P-FD, rPCC not computable for 1 of 5 clips" in out
    other = partner_stem(missing)
    result = load_result(tmp_path / "res" / "result.json")
    assert result.coverage["not_computable"] == [
        {"clip": other, "metrics": list(PARTNER_KEYS), "reason": f"partner ground truth {gt / missing}.npz not found"}]
    assert result.coverage["extra"] == [missing]
    row = next(r for r in result.per_clip if r["clip"] == other)
    assert all(math.isnan(row[k]) for k in PARTNER_KEYS)
    assert all(math.isfinite(row[k]) for k in KEYS if k not in PARTNER_KEYS)
    assert other not in result.coverage["undefined"].get("pfd_exp", [])


def test_wrong_width_is_named(dataset, capsys):
    gt, pred = dataset
    np.save(pred / "dlgA_speaker1.npy", np.zeros((T, 53), np.float32))
    code, _, err = run(capsys, pred, "--gt", gt)
    assert code == 2 and "dlgA_speaker1.npy" in err and "56 values per frame" in err


def test_pickled_prediction_npz_is_refused(dataset, tmp_path, capsys):
    gt, _ = dataset
    archive = tmp_path / "preds.npz"
    np.savez(archive, dlgA_speaker1=np.array([{"x": 1}], dtype=object))
    code, _, err = run(capsys, archive, "--gt", gt)
    assert code == 2 and "preds.npz[dlgA_speaker1]" in err and "pickled" in err


def test_empty_inputs(dataset, tmp_path, capsys):
    gt, _ = dataset
    empty = tmp_path / "empty"
    empty.mkdir()
    code, _, err = run(capsys, empty, "--gt", gt)
    assert code == 2 and "no .npy predictions" in err
    code, _, err = run(capsys, gt, "--gt", empty)
    assert code == 2 and "no DualTalk ground truth" in err
    with pytest.raises(InputError, match="no items"):
        score_arrays([])


def test_bad_prediction_name(dataset, capsys):
    gt, pred = dataset
    np.save(pred / "dlgA_listener.npy", np.zeros((T, 56)))
    code, out, _ = run(capsys, pred, "--gt", gt, "--strict")  # a name without ground truth: extra, not fatal
    assert code == 0 and "1 prediction(s) without ground truth" in out and "dlgA_listener" in out
    assert "named like dlgA_speaker1" in out


def test_length_mismatch_is_truncated_and_counted(dataset, tmp_path, capsys):
    gt, pred = dataset
    original = np.load(pred / "dlgC_speaker2.npy")
    np.save(pred / "dlgC_speaker2.npy", np.vstack([original, original[:7]]))
    code, out, _ = run(capsys, pred, "--gt", gt, "--out", tmp_path / "long")
    assert code == 0 and "1 clip(s) truncated" in out
    results, frame = _results(tmp_path / "long")
    assert results["coverage"]["truncated"] == [
        {"clip": "dlgC_speaker2", "pred": T + 7, "gt": T, "partner": T, "used": T}]
    np.save(pred / "dlgC_speaker2.npy", original)
    run(capsys, pred, "--gt", gt, "--out", tmp_path / "exact")
    assert frame.equals(_results(tmp_path / "exact")[1])


def test_too_short_clip_is_excluded(dataset, tmp_path, capsys):
    gt, pred = dataset
    np.save(pred / "dlgA_speaker1.npy", np.load(pred / "dlgA_speaker1.npy")[:30])
    code, out, _ = run(capsys, pred, "--gt", gt, "--out", tmp_path / "res")
    assert code == 0 and "only 30 common frames" in out
    assert _results(tmp_path / "res")[0]["excluded"][0]["clip"] == "dlgA_speaker1"


def test_short_clips_give_undefined_diversity_with_a_note(tmp_path, capsys):
    rng = np.random.default_rng(1)
    items = [ScoreItem(f"c{i}_speaker1", _smooth(rng, t), _smooth(rng, t), _smooth(rng, t))
             for i, t in enumerate((60, 120, 130))]
    report = score_arrays(items)
    assert report.coverage["undefined"]["div_pred_exp"] == ["c0_speaker1"]
    assert any("div_pred_exp undefined for 1 of 3 clips" in n for n in report.notes)
    defined = [row["div_pred_exp"] for row in report.per_item[1:]]
    assert report.metrics["div_pred_exp"] == pytest.approx(np.mean(defined))


def test_score_arrays_without_partner_scores_the_rest():
    rng = np.random.default_rng(2)
    pred, gt = _smooth(rng), _smooth(rng)
    report = score_arrays([ScoreItem("x_speaker1", pred, gt)])
    assert report.coverage["not_computable"][0]["reason"] == "no partner ground truth given (partner=None)"
    assert math.isnan(report.metrics["pfd_exp"]) and math.isnan(report.metrics["rpcc_jaw"])
    assert report.metrics["mse_exp"] == pytest.approx(np.mean((pred[:, :50] - gt[:, :50]) ** 2), rel=1e-12)


def test_seed_changes_only_diversity(dataset):
    gt, pred = dataset
    a, b = score_paths(pred, gt, seed=0), score_paths(pred, gt, seed=1)
    for key in KEYS:
        same = a.metrics[key] == b.metrics[key]
        assert same != key.startswith("div_"), key


@pytest.mark.skipif(not DEMO.is_dir(), reason="DualTalk demo clips not available")
def test_real_demo_clips_score_without_their_missing_partners(tmp_path, capsys):
    """The released demo clips (one participant's npz each): every metric without the partner is scored,
    P-FD and rPCC are not computable and say why. A copy of the ground truth scores MSE = STS = 0,
    FD ~ 0 and Var = Var-GT, Div = Div-GT (same draws)."""
    pred = tmp_path / "pred"
    pred.mkdir()
    stems = sorted(f.stem for f in DEMO.glob("*.npz"))
    assert len(stems) == 2
    for stem in stems:
        np.save(pred / f"{stem}.npy", load_gt_npz(DEMO / f"{stem}.npz"))
    code, out, err = run(capsys, pred, "--gt", DEMO, "--out", tmp_path / "res", "--strict")
    assert code == 0, err
    assert "scored 2 of 2; 2 of them without pfd, rpcc" in out
    result = load_result(tmp_path / "res" / "result.json")
    missing = {e["clip"]: e["reason"] for e in result.coverage["not_computable"]}
    assert missing == {s: f"partner ground truth {DEMO / partner_stem(s)}.npz not found" for s in stems}
    for key in PARTNER_KEYS:
        assert math.isnan(result.metrics[key])
    for c in ("exp", "jaw", "pose"):
        assert result.metrics[f"mse_{c}"] == 0.0 and result.metrics[f"sts_{c}"] == 0.0
        assert abs(result.metrics[f"fd_{c}"]) < 1e-6
        assert result.metrics[f"var_pred_{c}"] == result.metrics[f"var_gt_{c}"]
        assert result.metrics[f"div_pred_{c}"] == result.metrics[f"div_gt_{c}"]


@pytest.mark.skipif(not DEMO.is_dir(), reason="DualTalk demo clips not available")
def test_real_demo_clip_scores_against_itself(tmp_path):
    gt = tmp_path / "gt"
    gt.mkdir()
    source = DEMO / "xkHwlcDSOjc_sub_video_109_000_speaker1.npz"
    shutil.copy(source, gt / "demo_speaker1.npz")
    partner = DEMO / "UbjUDM1MiGE_sub_video_72_speaker2.npz"
    shutil.copy(partner, gt / "demo_speaker2.npz")  # a real partner (shorter: 587 frames)
    pred = tmp_path / "pred"
    pred.mkdir()
    np.save(pred / "demo_speaker1.npy", load_gt_npz(source))
    report = score_paths(pred, gt)
    assert report.coverage["expected"] == 2 and report.coverage["missing"] == ["demo_speaker2"]
    assert report.metrics["mse_exp"] == 0.0 and report.metrics["rpcc_pose"] == 0.0
    assert abs(report.metrics["fd_exp"]) < 1e-9
    assert report.coverage["truncated"][0]["used"] == 587


def test_split_names_a_sub_folder_of_the_root(dataset, tmp_path, capsys):
    gt, pred = dataset
    root = tmp_path / "DualTalk"
    root.mkdir()
    gt.rename(root / "test")
    code, out, _ = run(capsys, pred, "--gt", root, "--split", "test")
    assert code == 0 and "scored 6 of 6" in out
    code, _, err = run(capsys, pred, "--gt", root, "--split", "ood")
    assert code == 2 and "ood" in err and "split folder" in err


def test_predictions_without_ground_truth_are_extra_not_fatal(dataset, tmp_path, capsys):
    gt, pred = dataset
    for f in gt.glob("dlgC_*.npz"):
        f.unlink()
    code, out, _ = run(capsys, pred, "--gt", gt, "--out", tmp_path / "res", "--strict")
    assert code == 0 and "scored 4 of 4" in out and "2 prediction(s) without ground truth" in out
    assert _results(tmp_path / "res")[0]["coverage"]["extra"] == ["dlgC_speaker1", "dlgC_speaker2"]


def test_partner_metrics_average_over_clips_with_a_partner(dataset):
    """With dlgB's and dlgC's speaker2 ground truth gone, P-FD/rPCC are the mean over dlgA's two agents
    (the values the complete set gives them); every other value of dlgB/dlgC_speaker1 is unchanged."""
    gt, pred = dataset
    full = {row["clip"]: row for row in score_paths(pred, gt).per_item}
    for clip in ("dlgB", "dlgC"):
        (gt / f"{clip}_speaker2.npz").unlink()
    partial = score_paths(pred, gt)
    assert [e["clip"] for e in partial.coverage["not_computable"]] == ["dlgB_speaker1", "dlgC_speaker1"]
    for key in PARTNER_KEYS:
        assert partial.metrics[key] == pytest.approx((full["dlgA_speaker1"][key] + full["dlgA_speaker2"][key]) / 2,
                                                     rel=1e-12)
    rows = {row["clip"]: row for row in partial.per_item}
    for stem in ("dlgB_speaker1", "dlgC_speaker1"):
        for key in KEYS:
            if key not in PARTNER_KEYS:
                assert rows[stem][key] == pytest.approx(full[stem][key], rel=1e-9, abs=1e-12), key


def test_a_clip_whose_metrics_fail_is_excluded_not_fatal(monkeypatch):
    from dyadbench.metrics import dualtalk as suite

    original = suite.clip_metrics

    def failing_for_one(pred, gt, partner, *, seed):
        if pred[0, 0] == 123.0:
            raise ValueError("Fréchet distance: imaginary component 0.5 in sqrtm(S1 S2)")
        return original(pred, gt, partner, seed=seed)

    monkeypatch.setattr(suite, "clip_metrics", failing_for_one)
    rng = np.random.default_rng(3)
    bad = _smooth(rng)
    bad[0, 0] = 123.0
    items = [ScoreItem("a_speaker1", bad, _smooth(rng), _smooth(rng)),
             ScoreItem("b_speaker1", _smooth(rng), _smooth(rng), _smooth(rng))]
    report = score_arrays(items)
    assert report.n_scored == 1
    assert report.excluded == [{"clip": "a_speaker1",
                                "reason": "could not be scored: Fréchet distance: imaginary component 0.5 "
                                          "in sqrtm(S1 S2)"}]
