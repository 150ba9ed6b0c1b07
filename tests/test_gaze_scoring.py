"""The gaze–head suite end to end: in-memory scoring, reference rows, the style hook, and `dyadbench score`."""

import json

import numpy as np
import pytest
from click.testing import CliRunner
from scipy.ndimage import gaussian_filter1d

from dyadbench.cli import cli
from dyadbench.scoring.gaze import GazeSuiteConfig, score_arrays
from dyadbench.scoring.report import ScoreItem
from dyadbench.synth.gaze import make_gaze_sessions
from dyadbench.synth.gaze_writer import write_gaze_split


@pytest.fixture(scope="module")
def clips():
    return make_gaze_sessions("test", 8, seed=0, duration_s=30)


def items(clips, predict):
    return [ScoreItem(stem=f"{c.clip_id}_subject", pred=predict(i, c), gt=c.participants[0].motion,
                      audio=c.participants[0].audio, identity=c.participants[0].identity)
            for i, c in enumerate(clips)]


def gt_of(i, c):
    return c.participants[0].motion


@pytest.fixture(scope="module")
def gt_report(clips):
    return score_arrays(items(clips, gt_of), seed=0)


def test_ground_truth_against_itself(gt_report):
    m = gt_report.metrics
    for key in ("mae_all", "vel_gaze", "vel_abs_head", "mee_all", "mee_frame_gaze"):
        assert m[key] == 0.0
    assert m["sim_gt"] == 1.0 and m["sim_gt_seq"] == 1.0
    assert m["fix_ratio"] == m["gt_fix_ratio"] and m["comp_score"] == m["gt_comp_score"]
    assert m["saccade_ratio"] == pytest.approx(1 - m["fix_ratio"])
    assert gt_report.scaled["fix_ratio"] == pytest.approx(100 * m["fix_ratio"])
    assert gt_report.complete and gt_report.n_scored == 8
    assert gt_report.config["skip_frames"] == 50 and gt_report.config["seed"] == 0
    assert gt_report.config["idt_eyes"] == "pooled"
    assert "SimScore" in gt_report.table()
    directions = gt_report.config["higher_is_better"]
    assert directions["mae_all"] is False and directions["sim_gt_seq"] is True and directions["bas_delta_head"]
    assert directions["fix_ratio"] is None and set(directions) == set(m)


def test_speech_linked_head_beats_beat_shuffled_speech(gt_report):
    m = gt_report.metrics
    assert m["bas_delta_head"] > 0.03  # head beats follow the session's own speech, not another's
    assert m["bas_head"] == pytest.approx(m["bas_shuffled_head"] + m["bas_delta_head"])
    assert m["gt_bas_head"] == m["bas_head"]
    assert all(0 <= m[f"bas_{g}"] <= 1 for g in ("all", "gaze", "head"))


def test_reference_rows_order_as_expected(clips, gt_report):
    smooth = score_arrays(items(clips, lambda i, c: gaussian_filter1d(gt_of(i, c).astype(float), 1.0, axis=0)))
    static = score_arrays(items(clips, lambda i, c: np.zeros_like(gt_of(i, c))))
    other = score_arrays(items(clips, lambda i, c: gt_of((i + 1) % len(clips), clips[(i + 1) % len(clips)])))
    # a 1-frame blur of GT is a plausible near-miss; a still face is far off
    assert 0.6 < smooth.metrics["sim_gt_seq"] < 0.95
    assert static.metrics["sim_gt_seq"] < smooth.metrics["sim_gt_seq"] - 0.3
    assert static.metrics["fix_ratio"] == 1.0 and static.metrics["comp_score"] == 0.0
    # split-level Sim cannot tell another session's real motion from the truth; Sim_seq can
    assert other.metrics["sim_gt"] == pytest.approx(1.0)
    assert other.metrics["sim_gt_seq"] < 0.95
    # the still output has no motion beats: BAS is NaN, with the reason in the notes
    assert np.isnan(static.metrics["bas_head"])
    assert any("BAS head: no motion beats" in n for n in static.notes)
    assert all("no motion beats" in row["bas_note_head"] for row in static.per_item)
    assert "bas_note_head" not in gt_report.per_item[0]


def test_seed_frames_are_excluded(clips):
    def corrupt_seed(i, c):
        p = gt_of(i, c).copy()
        p[:50] += 20.0
        return p
    report = score_arrays(items(clips[:2], corrupt_seed))
    assert report.metrics["mae_all"] == 0.0
    assert score_arrays(items(clips[:2], corrupt_seed), config=GazeSuiteConfig(skip_frames=0)).metrics["mae_all"] > 0


def test_bad_predictions_are_excluded_with_reasons(clips):
    preds = items(clips[:3], gt_of)
    nan_pred = preds[0].pred.copy()
    nan_pred[60, 2] = np.nan
    preds[0] = ScoreItem(preds[0].stem, nan_pred, preds[0].gt, audio=preds[0].audio)
    preds[1] = ScoreItem(preds[1].stem, preds[1].pred[:40], preds[1].gt, audio=preds[1].audio)
    longer = np.concatenate([preds[2].pred, preds[2].pred[:10]])
    preds[2] = ScoreItem(preds[2].stem, longer, preds[2].gt, audio=preds[2].audio)
    report = score_arrays(preds)
    reasons = {e["clip"]: e["reason"] for e in report.excluded}
    assert "NaN" in reasons[preds[0].stem] and "seed frames" in reasons[preds[1].stem]
    assert report.n_scored == 1 and not report.complete
    assert any("differ in length" in n for n in report.notes)
    assert any("at least 2 sequences" in n for n in report.notes)  # no derangement of one sequence


def test_jobs_do_not_change_numbers(clips):
    one = score_arrays(items(clips[:3], lambda i, c: gaussian_filter1d(gt_of(i, c), 2.0, axis=0)), jobs=1)
    two = score_arrays(items(clips[:3], lambda i, c: gaussian_filter1d(gt_of(i, c), 2.0, axis=0)), jobs=2)
    assert json.dumps(one.metrics, sort_keys=True) == json.dumps(two.metrics, sort_keys=True)


class WindowStats:
    """A deterministic stand-in encoder for testing the hook: per-dim mean and std of each window."""

    digest = "window-stats-v1"
    window, hop = 50, 25

    def __call__(self, windows):
        return np.concatenate([windows.mean(axis=1), windows.std(axis=1), np.ones((len(windows), 1))], axis=1)


def test_style_encoder_hook(clips):
    same = score_arrays(items(clips[:2], gt_of), style_encoder=WindowStats())
    assert same.metrics["style_ce"] == pytest.approx(0.0, abs=1e-12)
    assert same.config["style_encoder"] == "window-stats-v1"
    still = score_arrays(items(clips[:2], lambda i, c: np.zeros_like(gt_of(i, c))), style_encoder=WindowStats())
    assert still.metrics["style_ce"] > 0.1
    none = score_arrays(items(clips[:2], gt_of))
    assert "style_ce" not in none.metrics and any("style encoder" in n for n in none.notes)


def test_score_command_on_disk(tmp_path):
    write_gaze_split(tmp_path / "gt", split="test", clips=3, seed=2, duration_s=8)
    sessions = make_gaze_sessions("test", 3, seed=2, duration_s=8)
    preds = tmp_path / "preds"
    preds.mkdir()
    np.save(preds / f"{sessions[0].clip_id}_subject.npy", sessions[0].participants[0].motion)
    np.save(preds / f"{sessions[1].clip_id}.npy", sessions[1].participants[0].motion)  # bare session name
    np.save(preds / "unrelated_subject.npy", np.zeros((200, 7), np.float32))
    out = tmp_path / "out"
    result = CliRunner().invoke(cli, ["score", str(preds), "--suite", "gaze", "--gt", str(tmp_path / "gt" / "test"),
                                      "--out", str(out)])
    assert result.exit_code == 0, result.output
    assert "scored 2 of 3" in result.output and "SimScore" in result.output
    saved = json.loads((out / "result.json").read_text())
    assert saved["metrics"]["sim_gt"] == 1.0 and saved["metrics"]["mae_all"] == 0.0
    assert saved["coverage"]["missing"] == [f"{sessions[2].clip_id}_subject"]
    assert saved["coverage"]["extra"] == ["unrelated_subject"]
    strict = CliRunner().invoke(cli, ["score", str(preds), "--suite", "gaze", "--gt", str(tmp_path / "gt"),
                                      "--split", "test", "--strict"])
    assert strict.exit_code == 1


def test_score_command_names_a_bad_prediction(tmp_path):
    write_gaze_split(tmp_path / "gt", split="test", clips=1, seed=2, duration_s=8)
    preds = tmp_path / "preds"
    preds.mkdir()
    np.save(preds / "test000_spk1_subject.npy", np.zeros((200, 6), np.float32))
    from dyadbench.cli import main
    with pytest.raises(SystemExit) as exc:
        main(["score", str(preds), "--suite", "gaze", "--gt", str(tmp_path / "gt")])
    assert exc.value.code == 2
