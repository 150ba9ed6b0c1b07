"""MAE / Vel / MEE, CompScore, SimWithGT and the style cosine error: analytic cases and properties."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from dyadbench.errors import InputError
from dyadbench.metrics import gaze

motions = arrays(np.float64, st.tuples(st.integers(2, 30), st.just(7)), elements=st.floats(-40, 40))


def sweep(head_py=(0.0, 0.0), eye_py=(0.0, 0.0), frames=11):
    """Constant velocities (deg/frame): head (pitch, yaw) and both eyes (pitch, yaw)."""
    t = np.arange(frames)[:, None]
    m = np.zeros((frames, 7))
    m[:, 0:2] = t * np.asarray(head_py)
    m[:, 3:5] = m[:, 5:7] = t * np.asarray(eye_py)
    return m


# --- MAE / Vel / MEE -------------------------------------------------------------------------------------

def test_constant_offset():
    rng = np.random.default_rng(0)
    gt = rng.normal(0, 5, (40, 7))
    for group in gaze.GROUPS:
        assert gaze.mae(gt + 1.5, gt, group) == pytest.approx(1.5)
        assert gaze.vel(gt + 1.5, gt, group) == pytest.approx(0.0, abs=1e-24)
        assert gaze.mee(gt + 1.5, gt, group) == pytest.approx(0.0, abs=1e-12)


def test_group_identities():
    rng = np.random.default_rng(1)
    pred, gt = rng.normal(0, 5, (50, 7)), rng.normal(0, 5, (50, 7))
    for fn in (gaze.mae, gaze.vel, gaze.vel_abs):
        assert fn(pred, gt, "all") == pytest.approx((4 * fn(pred, gt, "gaze") + 3 * fn(pred, gt, "head")) / 7)
    assert gaze.mee(pred, gt, "all") <= gaze.mee(pred, gt, "gaze") + gaze.mee(pred, gt, "head") + 1e-12


def test_hand_computed_velocity_and_energy():
    gt = np.zeros((3, 7))
    pred = np.zeros((3, 7))
    pred[:, 0] = [0.0, 2.0, 2.0]  # head pitch velocities 2, 0
    # Vel_head = mean over 2 frames x 3 dims of squared error = (4 + 0) / 6
    assert gaze.vel(pred, gt, "head") == pytest.approx(4 / 6)
    assert gaze.vel_abs(pred, gt, "head") == pytest.approx(2 / 6)
    # energy = mean over frames of the sum over dims of (dx)^2 = (4 + 0) / 2
    assert gaze.motion_energy(pred, "head") == pytest.approx(2.0)
    assert gaze.mee(pred, gt, "head") == pytest.approx(2.0)
    assert gaze.mee(pred, gt, "gaze") == 0.0
    assert gaze.mee_frame(pred, gt, "all") == pytest.approx(2.0)


def test_mismatched_or_bad_arrays_are_named():
    with pytest.raises(InputError, match="differ in length"):
        gaze.mae(np.zeros((5, 7)), np.zeros((6, 7)))
    with pytest.raises(InputError, match=r"\(T, 7\)"):
        gaze.mae(np.zeros((5, 6)), np.zeros((5, 6)))
    with pytest.raises(InputError, match="NaN"):
        gaze.mae(np.full((5, 7), np.nan), np.zeros((5, 7)))


@settings(max_examples=60, deadline=None)
@given(motions)
def test_zero_on_identical_input(m):
    for group in gaze.GROUPS:
        for fn in (gaze.mae, gaze.vel, gaze.vel_abs, gaze.mee, gaze.mee_frame):
            assert fn(m, m.copy(), group) == 0.0


@settings(max_examples=60, deadline=None)
@given(motions, st.data())
def test_error_metrics_symmetric_and_non_negative(a, data):
    b = data.draw(arrays(np.float64, a.shape, elements=st.floats(-40, 40)))
    for fn in (gaze.mae, gaze.vel, gaze.mee):
        assert fn(a, b) >= 0
        assert fn(a, b) == pytest.approx(fn(b, a))


# --- CompScore ---------------------------------------------------------------------------------------------

def test_vor_head_rotation_scores_minus_head_speed():
    # head yaw 0.5 deg/frame with exact VOR (eye = -head): g = 0 -> score -|h| = -0.5
    m = sweep(head_py=(0.0, 0.5), eye_py=(0.0, -0.5))
    assert gaze.comp_score([m]) == pytest.approx(-0.5)
    # in deg/s the same motion scores -12.5 (velocities x 25)
    assert gaze.comp_score([m], velocity_unit="deg_per_s") == pytest.approx(-12.5)


def test_head_only_motion_with_still_eyes():
    # h = (0.3, 0.4) deg/frame, e = 0: g = h, |g| = 0.5 < 20 -> score -|h| = -0.5 every frame
    assert gaze.comp_score([sweep(head_py=(0.3, 0.4))]) == pytest.approx(-0.5)
    # h = 30 deg/frame with still eyes: |g| = 30 is in the shift band but e = 0, the angle is undefined -> 0
    assert gaze.comp_score([sweep(head_py=(0.0, 30.0))]) == 0.0
    # roll is not part of h, unless asked for in the -|h| branch: |(0, 0.3, 0.4)| = 0.5
    m = np.zeros((11, 7))
    m[:, 2] = 5.0 * np.arange(11)
    assert gaze.comp_score([m]) == 0.0
    m = sweep(head_py=(0.0, 0.3))
    m[:, 2] = 0.4 * np.arange(11)
    assert gaze.comp_score([m]) == pytest.approx(-0.3)
    assert gaze.comp_score([m], include_roll=True) == pytest.approx(-0.5)


def test_shift_band_cases():
    # eye and head together at 30 deg/frame each: |g| = 60, cos = 1 -> -1
    assert gaze.comp_score([sweep(head_py=(0, 30), eye_py=(0, 30))]) == pytest.approx(-1.0)
    # head 30, eyes -60 (opposite): |g| = 30, cos = -1 -> +1
    assert gaze.comp_score([sweep(head_py=(0, 30), eye_py=(0, -60))]) == pytest.approx(1.0)
    # |g| = 22 lies in the 20-25 gap -> 0
    assert gaze.comp_score([sweep(head_py=(0, 11), eye_py=(0, 11))]) == 0.0
    # perpendicular head and eyes: cos = 0 -> 0; |g| = 50
    assert gaze.comp_score([sweep(head_py=(30, 0), eye_py=(0, 40))]) == pytest.approx(0.0)
    # above the band (|g| > 90) -> 0
    assert gaze.comp_score([sweep(head_py=(0, 50), eye_py=(0, 50))]) == 0.0


def test_comp_score_uses_mean_of_both_eyes():
    m = sweep(head_py=(0, 0.5))
    m[:, 4] = -1.0 * np.arange(11)  # left yaw -1/frame, right eye still -> e = -0.5 -> g = 0 -> -0.5
    assert gaze.comp_score([m]) == pytest.approx(-0.5)


def test_comp_score_pools_velocity_frames():
    a = sweep(head_py=(0, 0.5), frames=3)  # 2 velocity frames of -0.5
    b = sweep(head_py=(0, 1.0), frames=5)  # 4 velocity frames of -1.0
    assert gaze.comp_score([a, b]) == pytest.approx((2 * -0.5 + 4 * -1.0) / 6)


# --- SimWithGT ---------------------------------------------------------------------------------------------

@pytest.mark.parametrize("fix, comp, expected", [
    (0.7417, -0.2890, 0.8220), (0.7098, -0.3021, 0.8670), (0.6922, -0.3054, 0.8879),
    (0.6733, -0.3100, 0.9114), (0.8457, -0.2006, 0.6296), (0.7572, -0.3860, 0.8047)])
def test_sim_reproduces_published_table3(fix, comp, expected):
    assert round(gaze.sim_with_gt(0.6113, -0.3366, fix, comp), 4) == expected


@settings(max_examples=100, deadline=None)
@given(*(st.floats(-2, 2) for _ in range(4)))
def test_sim_at_most_one(a, b, c, d):
    assert gaze.sim_with_gt(a, b, c, d) <= 1.0
    assert gaze.sim_with_gt(a, b, a, b) == 1.0


# --- style cosine error hook ----------------------------------------------------------------------------

def test_style_cosine_error():
    e = np.array([[1.0, 0.0], [0.0, 2.0]])
    assert gaze.style_cosine_error(e, e) == 0.0
    assert gaze.style_cosine_error(e, -e) == pytest.approx(2.0)
    assert gaze.style_cosine_error(e, np.array([[0.0, 1.0], [0.0, 1.0]])) == pytest.approx(0.5)
    assert np.isnan(gaze.style_cosine_error(np.zeros((0, 2)), np.zeros((0, 2))))
    with pytest.raises(InputError, match="zero norm"):
        gaze.style_cosine_error(np.zeros((1, 2)), e[:1])


def test_sliding_windows():
    m = np.arange(70, dtype=float)[:, None].repeat(7, 1)
    w = gaze.sliding_windows(m, 50, 10)
    assert w.shape == (3, 50, 7) and w[2, 0, 0] == 20.0
    assert gaze.sliding_windows(m[:10], 50, 10).shape == (0, 50, 7)


def test_every_metric_declares_its_direction():
    assert gaze.METRICS["mae"].higher_is_better is False
    assert gaze.METRICS["sim_gt"].higher_is_better is True
    assert gaze.METRICS["fix_ratio"].higher_is_better is None  # closer to the ground truth
