"""Synthetic gaze–head sessions: determinism, structure, and calibration against the paper's GT statistics."""

import numpy as np
import pytest

from dyadbench.datasets.layouts import get_layout
from dyadbench.metrics.gaze import comp_score, fix_ratio
from dyadbench.synth import gaze as synth

# StyGazeTalk Table 3, ground truth of real conversation (HAGE test split), and the tolerance we hold the
# generator to: +-5 points of fixation and +-0.05 of CompScore, on every seed.
PAPER_FIX, PAPER_COMP = 0.6113, -0.3366
FIX_TOL, COMP_TOL = 0.05, 0.05


def motions(clips):
    return [c.participants[0].motion for c in clips]


def test_deterministic_and_seeded():
    a = synth.make_gaze_session("test", 1, seed=5, duration_s=6)
    b = synth.make_gaze_session("test", 1, seed=5, duration_s=6)
    c = synth.make_gaze_session("test", 1, seed=6, duration_s=6)
    np.testing.assert_array_equal(a.participants[0].motion, b.participants[0].motion)
    np.testing.assert_array_equal(a.participants[0].audio, b.participants[0].audio)
    assert not np.array_equal(a.participants[0].motion, c.participants[0].motion)
    assert a.clip_id == "test001_spk2" and a.participants[0].identity == "spk2"
    assert a.participants[0].motion.shape == (150, 7) and a.participants[0].audio.shape == (150 * 640,)
    assert a.meta["seed"] == 5 and a.meta["preset"] == "hage-like"


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_ground_truth_lands_on_the_papers_gaze_statistics(seed):
    clips = synth.make_gaze_sessions("test", 8, seed=seed, duration_s=45)
    assert fix_ratio(motions(clips)) == pytest.approx(PAPER_FIX, abs=FIX_TOL)
    assert comp_score(motions(clips)) == pytest.approx(PAPER_COMP, abs=COMP_TOL)


def test_saccades_are_fast_and_fixations_drift():
    m = np.concatenate(motions(synth.make_gaze_sessions("test", 4, seed=0, duration_s=30))).astype(float)
    eye_v = np.diff((m[:, 3:5] + m[:, 5:7]) / 2, axis=0)
    speed_deg_s = np.hypot(eye_v[:, 0], eye_v[:, 1]) * 25.0
    assert np.percentile(speed_deg_s, 99) > 200.0  # saccades reach hundreds of deg/s
    assert np.mean(speed_deg_s > 30.0) > 0.1
    assert np.median(speed_deg_s) > 0.0  # no frame-to-frame standstill: drift and tracker noise


def test_head_takes_part_of_gaze_shifts():
    m = np.concatenate(motions(synth.make_gaze_sessions("test", 8, seed=0, duration_s=30))).astype(float)
    gaze_in_space_yaw = (m[:, 4] + m[:, 6]) / 2 + m[:, 1]
    slope = np.polyfit(gaze_in_space_yaw, m[:, 1], 1)[0]
    assert 0.05 < slope < 0.6  # the head moves with the gaze, but only partly: the eyes do the rest


def test_speakers_have_consistent_distinct_styles():
    clips = synth.make_gaze_sessions("train", 16, seed=0, duration_s=30)  # every speaker twice
    per_session = np.array([fix_ratio([m]) for m in motions(clips)]).reshape(2, 8)
    assert np.ptp(per_session.mean(axis=0)) > 0.15  # speakers differ
    assert np.corrcoef(per_session[0], per_session[1])[0, 1] > 0.5  # and stay themselves across sessions


def test_speech_while_speaking_only():
    clip = synth.make_gaze_session("test", 0, seed=0, duration_s=30)
    speaking = clip.meta["speaking"]["subject"]
    assert 0.2 < speaking.mean() < 0.8
    frames_rms = np.sqrt(np.mean(clip.participants[0].audio.reshape(-1, 640).astype(float) ** 2, axis=1))
    assert frames_rms[speaking].mean() > 10 * frames_rms[~speaking].mean()


def test_ood_speakers_lie_outside_the_training_ranges():
    for speaker in synth.OOD_SPEAKERS:
        style = synth.speaker_style(speaker, seed=0)
        outside = [name for name, (lo, hi) in synth.PRESETS["hage-like"].items()
                   if not lo <= getattr(style, name) <= hi]
        assert len(outside) == len(synth.PRESETS["hage-like"])


def test_write_through_the_layout_registry(tmp_path):
    summary = get_layout("gaze").write(tmp_path, split="val", clips=2, seed=0, jobs=1)
    assert summary["sessions"] == 2 and summary["seed"] == 0
    assert sorted(p.name for p in (tmp_path / "val").iterdir()) == [
        ".dyadbench-output", "val000_spk1.npz", "val000_spk1.wav", "val001_spk2.npz", "val001_spk2.wav"]
    assert get_layout("gaze").validate(tmp_path).ok
