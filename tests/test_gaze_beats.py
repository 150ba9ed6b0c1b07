"""BAS: motion beats, speech onsets, the alignment score, and its shuffled-speech reference."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from dyadbench.metrics import beats
from dyadbench.scoring.gaze import derangement

FPS = 25.0


def head_with_speed_minima(minima_frames, frames=100):
    """(T, 7) motion whose head-yaw speed has strict minima exactly at ``minima_frames`` (frame of x_t - x_{t-1})."""
    t = np.arange(1, frames)
    speed = np.full(frames - 1, 2.0)
    for f in minima_frames:
        speed = np.minimum(speed, 0.25 + 0.25 * np.abs(t - f))  # V-shaped dip at frame f (exact in binary)
    m = np.zeros((frames, 7))
    m[1:, 1] = np.cumsum(speed)
    return m


def test_motion_beats_found_at_constructed_minima():
    m = head_with_speed_minima([20, 45, 70])
    np.testing.assert_allclose(beats.motion_beats(m, "head", fps=FPS), np.array([20, 45, 70]) / FPS)
    # eyes still: no gaze beats; "all" sees the head
    assert len(beats.motion_beats(m, "gaze", fps=FPS)) == 0
    np.testing.assert_allclose(beats.motion_beats(m, "all", fps=FPS), np.array([20, 45, 70]) / FPS)


def test_bas_is_one_on_coincident_beats_and_decreases_with_offset():
    m = head_with_speed_minima([20, 45, 70])
    onsets = np.array([20, 45, 70]) / FPS
    mb = beats.motion_beats(m, "head", fps=FPS)
    assert beats.beat_alignment(mb, onsets) == pytest.approx(1.0)
    assert beats.beat_alignment(mb, onsets, direction="a2m") == pytest.approx(1.0)
    sigma = beats.SIGMA_S
    # every beat off by sigma -> exp(-1/2)
    assert beats.beat_alignment(mb, onsets + sigma) == pytest.approx(np.exp(-0.5))
    scores = [beats.beat_alignment(mb, onsets + d) for d in (0.0, 0.02, 0.04, 0.08, 0.16)]
    assert all(a > b for a, b in zip(scores, scores[1:]))


def test_bas_one_beat_off_by_sigma():
    mb = np.array([1.0, 2.0, 3.0])
    assert beats.beat_alignment(mb, np.array([1.0, 2.0, 3.05])) == pytest.approx((2 + np.exp(-0.5)) / 3)


def test_bas_directions_differ():
    mb = np.array([1.0])
    onsets = np.array([1.0, 2.0])
    assert beats.beat_alignment(mb, onsets, direction="m2a") == 1.0
    # a2m: onset 2.0 is 1 s from the only motion beat -> exp(-1 / (2 * 0.05^2)) ~ 0
    assert beats.beat_alignment(mb, onsets, direction="a2m") == pytest.approx(0.5)


def test_bas_empty_is_nan_with_a_reason():
    assert np.isnan(beats.beat_alignment(np.zeros(0), np.array([1.0])))
    assert beats.beat_alignment(np.zeros(0), np.array([1.0]), empty_policy="zero") == 0.0
    assert np.isnan(beats.beat_alignment(np.array([1.0]), np.zeros(0)))
    assert "no motion beats" in beats.empty_reason(0, 4)
    assert "no speech onsets" in beats.empty_reason(3, 0)
    assert beats.empty_reason(3, 4) is None
    # a still head has no strict speed minima
    assert len(beats.motion_beats(np.zeros((50, 7)), "head")) == 0


def test_min_speed_filter_drops_jitter_beats():
    rng = np.random.default_rng(0)
    jitter = np.zeros((100, 7))
    jitter[:, 0] = rng.normal(0, 1e-6, 100)
    assert len(beats.motion_beats(jitter, "head")) > 0
    assert len(beats.motion_beats(jitter, "head", min_speed=0.01)) == 0


def tone_bursts(starts_s, seconds=3.0, sr=16_000):
    rng = np.random.default_rng(0)
    audio = rng.normal(0, 1e-3, int(seconds * sr))
    n = int(0.15 * sr)
    tone = 0.3 * np.sin(2 * np.pi * 150 * np.arange(n) / sr) * np.hanning(n)
    for s in starts_s:
        audio[int(s * sr):int(s * sr) + n] += tone
    return audio.astype(np.float32)


def test_speech_onsets_at_syllable_starts():
    starts = [0.5, 1.3, 2.1]
    onsets = beats.speech_onsets(tone_bursts(starts))
    assert len(onsets) >= 3
    # every onset lies within 3 frames of a burst start, and every burst has one
    dist = np.abs(onsets[:, None] - np.array(starts)[None, :]).min(axis=1)
    assert dist.max() <= 3 / FPS
    assert all(np.abs(onsets - s).min() <= 3 / FPS for s in starts)
    assert len(beats.speech_onsets(np.zeros(16_000, np.float32))) == 0


def test_peak_pick_matches_librosa_semantics():
    x = np.array([0.0, 0.1, 1.0, 0.2, 0.0, 0.0, 0.9, 0.95, 0.1, 0.0])
    # post_max 1, pre_max 0: the max filter is the sample itself; threshold = centred 5-sample mean + delta
    picks = beats.peak_pick(x, **beats.PEAK_PICK)
    mean5 = np.array([np.mean(np.clip(np.arange(i - 2, i + 3), 0, 9).choose(x)) for i in range(10)])
    assert picks.tolist() == np.flatnonzero((x > 0) & (x >= mean5 + 0.07)).tolist()
    # with a 3-sample max window only local maxima survive
    assert beats.peak_pick(x, pre_max=1, post_max=2, pre_avg=2, post_avg=3, delta=0.07, wait=0).tolist() == [2, 7]


@settings(max_examples=50, deadline=None)
@given(st.integers(2, 40), st.integers(0, 1000))
def test_derangement_has_no_fixed_points(n, seed):
    perm = derangement(n, seed)
    assert sorted(perm.tolist()) == list(range(n))
    assert not np.any(perm == np.arange(n))
    assert np.array_equal(perm, derangement(n, seed))


def test_derangement_of_one_is_none():
    assert derangement(1, 0) is None
