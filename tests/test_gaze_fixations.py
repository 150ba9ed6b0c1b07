"""I-DT fixation labelling: hand-computed goldens, both breaking-sample policies, eye modes, properties."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from dyadbench.errors import InputError
from dyadbench.metrics.fixations import FIXATION, INVALID, SACCADE, fixation_counts, fixation_spans, idt_labels
from dyadbench.metrics.gaze import fix_ratio


def both_eyes(pitch, yaw):
    """(T, 4) [L_pitch, L_yaw, R_pitch, R_yaw] with both eyes equal."""
    pitch, yaw = np.broadcast_arrays(np.asarray(pitch, float), np.asarray(yaw, float))
    return np.stack([pitch, yaw, pitch, yaw], axis=1)


def test_step_signal_fixations_without_breaking_sample():
    # 0 deg for 49 frames, one 9 deg sample, 1 deg for 50 frames (yaw and pitch alike)
    x = np.r_[np.zeros(49), [9.0], np.ones(50)]
    labels = idt_labels(both_eyes(x, x))
    assert fixation_spans(labels) == [(0, 49), (50, 100)]
    assert np.flatnonzero(labels == SACCADE).tolist() == [49]
    assert fixation_counts(labels) == (99, 1)


def test_step_signal_fixations_with_breaking_sample():
    # pymovements' variant counts the sample that broke the threshold in the fixation
    x = np.r_[np.zeros(49), [9.0], np.ones(50)]
    labels = idt_labels(both_eyes(x, x), include_breaking_sample=True)
    assert fixation_spans(labels) == [(0, 100)]
    assert fixation_counts(labels) == (100, 0)


def test_small_step_stays_one_fixation():
    # a 1-deg step in yaw: dispersion 1 <= 3.5, the whole signal is one fixation
    x = np.r_[np.zeros(20), np.ones(20)]
    assert fixation_spans(idt_labels(both_eyes(0.0, x))) == [(0, 40)]


def test_constant_signal_is_all_fixation_and_alternation_is_none():
    assert fix_ratio([np.zeros((60, 7))]) == 1.0
    alternating = np.where(np.arange(60) % 2, 5.0, -5.0)
    motion = np.zeros((60, 7))
    motion[:, 3:7] = both_eyes(0.0, alternating)
    assert fix_ratio([motion]) == 0.0


def test_windows_shorter_than_min_frames_are_saccades():
    labels = idt_labels(both_eyes(np.zeros(2), np.zeros(2)))
    assert labels.tolist() == [SACCADE, SACCADE]
    # two-frame plateaus separated by jumps never reach 3 frames
    x = np.repeat([0.0, 10.0, 20.0, 30.0], 2)
    assert fixation_counts(idt_labels(both_eyes(0.0, x))) == (0, 8)


def test_constant_velocity_sweep_above_idt_boundary_is_all_saccade():
    # 50 deg/s = 2 deg/frame in yaw: any 3 frames span 4 deg > 3.5 deg
    yaw = 2.0 * np.arange(100)
    assert fixation_counts(idt_labels(both_eyes(0.0, yaw))) == (0, 100)
    # a 30 deg/s diagonal sweep (1.2 deg/frame, 0.8485 per axis) spans 2 * 2 * 0.8485 = 3.39 deg: fixation
    # (cut into 3-frame fixations: 99 frames make 33 of them)
    step = 1.2 / np.sqrt(2.0)
    assert fixation_counts(idt_labels(both_eyes(step * np.arange(99), step * np.arange(99)))) == (99, 0)


def test_sweep_exactly_at_threshold():
    # one-axis sweep: 3 frames span 2 s; fixation iff 2 s <= 3.5 (the window never grows beyond 3 frames)
    at = idt_labels(both_eyes(0.0, 1.75 * np.arange(9)))
    assert fixation_counts(at) == (9, 0)  # three back-to-back 3-frame fixations
    above = idt_labels(both_eyes(0.0, 1.76 * np.arange(9)))
    assert fixation_counts(above) == (0, 9)


def test_pooled_eyes_see_vergence_cyclopean_does_not():
    gaze = np.zeros((30, 4))
    gaze[:, 1], gaze[:, 3] = 2.0, -2.0  # left yaw +2, right yaw -2: pooled dispersion 4 > 3.5
    assert fixation_counts(idt_labels(gaze, eyes="pooled")) == (0, 30)
    assert fixation_counts(idt_labels(gaze, eyes="cyclopean")) == (30, 0)


def test_invalid_frames_split_fixations_and_are_not_counted():
    gaze = np.zeros((20, 4))
    gaze[10] = np.nan
    valid = np.ones(20, bool)
    valid[15] = False
    labels = idt_labels(gaze, valid=valid)
    assert labels[10] == INVALID and labels[15] == INVALID
    assert fixation_spans(labels) == [(0, 10), (11, 15), (16, 20)]
    assert fixation_counts(labels) == (18, 0)


def test_bad_input_is_named():
    with pytest.raises(InputError, match="gaze"):
        idt_labels(np.zeros((10, 3)))
    with pytest.raises(InputError, match="eyes"):
        idt_labels(np.zeros((10, 4)), eyes="left")


def test_fix_ratio_pools_frame_counts_over_sequences():
    still = np.zeros((30, 7))
    moving = np.zeros((10, 7))
    moving[:, 4] = moving[:, 6] = 5.0 * np.arange(10)
    assert fix_ratio([still, moving]) == pytest.approx(30 / 40)


@settings(max_examples=60, deadline=None)
@given(arrays(np.float64, st.tuples(st.integers(0, 40), st.just(7)), elements=st.floats(-30, 30)),
       st.sampled_from(["pooled", "cyclopean"]), st.booleans())
def test_fix_ratio_is_a_fraction(motion, eyes, breaking):
    value = fix_ratio([motion], eyes=eyes, include_breaking_sample=breaking)
    assert np.isnan(value) if len(motion) == 0 else 0.0 <= value <= 1.0
    labels = idt_labels(motion[:, 3:7], eyes=eyes, include_breaking_sample=breaking)
    # every fixation span lasts at least 3 frames
    assert all(b - a >= 3 for a, b in fixation_spans(labels))
    assert set(np.unique(labels)) <= {FIXATION, SACCADE}
