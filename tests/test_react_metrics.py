"""REACT metrics: hand-computable cases, the spec's baseline values, errors, and the loop reference."""

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

import react_reference as ref
from dyadbench.errors import InputError
from dyadbench.metrics import react
from dyadbench.metrics.ccc import ccc, ccc_channels
from dyadbench.metrics.tlcc import MAX_LAG, tlcc_offsets


def problem(seed, n=6, r=3, t=60, density=0.4):
    rng = np.random.default_rng(seed)
    p = rng.random((n, r, t, 25))
    p[..., :15] = p[..., :15] > 0.5
    listener = rng.random((n, t, 25))
    listener[..., :15] = listener[..., :15] > 0.6
    speaker = rng.random((n, t, 25))
    s = (rng.random((n, n)) < density).astype(np.int64)
    s[np.arange(n), rng.integers(0, n, n)] = 1  # every row has a neighbour
    return p, listener, speaker, s


# --- CCC and TLCC -------------------------------------------------------------------------------------

def test_ccc_of_a_series_with_itself_is_one():
    x = np.random.default_rng(0).normal(size=(50, 25))
    values = ccc_channels(x, x)
    var = x.var(axis=0)
    np.testing.assert_allclose(values, 2 * var / (2 * var + 1e-8), rtol=1e-14)  # 1 up to the 1e-8 guard
    assert ccc(x, x) == pytest.approx(1.0, abs=1e-7)


def test_constant_channels_contribute_zero():
    x = np.random.default_rng(1).normal(size=(50, 4))
    x[:, 1] = 0.3
    values = ccc_channels(x, x)
    assert values[1] == 0.0
    assert ccc(x, x) == pytest.approx(3 / 4, abs=1e-7)
    y = x.copy()
    y[:, 2] = 7.0  # constant prediction channel
    assert ccc_channels(x, y)[2] == 0.0


def test_ccc_hand_computed():
    x = np.array([[1.0], [2.0], [3.0], [4.0]])
    y = 2 * x  # r = 1, var(x) = 1.25, var(y) = 5, means 2.5 and 5
    expected = 2 * 1.0 * np.sqrt(1.25) * np.sqrt(5.0) / (1.25 + 5.0 + 2.5 ** 2 + 1e-8)
    assert ccc(x, y) == pytest.approx(expected, rel=1e-15)


def test_tlcc_offset_of_a_delayed_copy():
    rng = np.random.default_rng(2)
    speaker = np.cumsum(rng.normal(size=(200, 25)), axis=0)
    for delay in (0, 3, 17):
        pred = np.concatenate([rng.normal(size=(delay, 25)), speaker[:200 - delay]])  # pred[t] = speaker[t-delay]
        assert tlcc_offsets(pred[None], speaker[None])[0] == delay


def test_constant_prediction_gives_frsyn_49():
    speaker = np.random.default_rng(3).random((4, 80, 25))
    pred = np.full((4, 2, 80, 25), 0.1)
    assert react.fr_syn(pred, speaker) == MAX_LAG == 49
    assert react.fr_syn(pred, speaker, all_reactions=True) == 49


# --- the spec's baselines -----------------------------------------------------------------------------

def test_random_baseline_values():
    rng = np.random.default_rng(4)
    p = rng.random((30, 10, 750, 25)).astype(np.float32)
    assert react.fr_div(p) == pytest.approx(1 / 6, rel=0.01)
    assert react.fr_var(p) == pytest.approx(1 / 12, rel=0.01)
    assert react.fr_dvs(p) == pytest.approx(1 / 6, rel=0.01)


def test_mean_frame_baseline_values():
    _, listener, speaker, s = problem(5, n=5, r=10, t=80)
    mean_frame = np.random.default_rng(6).random(25)
    p = np.broadcast_to(mean_frame, (5, 10, 80, 25))
    values = react.score(p, listener, speaker, s)
    assert values["FRCorr"] == 0.0
    assert values["FRDiv"] == values["FRVar"] == values["FRDvs"] == 0.0
    assert values["FRSyn"] == values["FRSyn_all"] == 49.0


def test_ground_truth_baseline():
    _, listener, speaker, s = problem(7, n=5, t=60)
    np.fill_diagonal(s, 1)
    p = np.repeat(listener[:, None], 10, axis=1)
    values = react.score(p, listener, speaker, s)
    assert values["FRDist"] == 0.0  # each sample's own listener is a neighbour at DTW 0
    assert values["FRDiv"] == 0.0
    assert values["FRCorr"] <= 10.0 and values["FRCorr"] == pytest.approx(ref.fr_corr(p, listener, s), rel=1e-12)


def test_frdiv_is_zero_for_identical_predictions():
    one = np.random.default_rng(8).random((4, 1, 30, 25))
    assert react.fr_div(np.repeat(one, 5, axis=1)) == 0.0
    assert react.fr_div(one) == 0.0  # R == 1


@settings(max_examples=15, deadline=None)
@given(st.integers(0, 10_000), st.integers(1, 4), st.integers(2, 5))
def test_diversity_properties(seed, r, n):
    p = np.random.default_rng(seed).random((n, r, 8, 25)).astype(np.float32)
    div, dvs = react.fr_div(p), react.fr_dvs(p)
    assert div >= 0 and dvs >= 0
    perm = np.random.default_rng(seed + 1).permutation(r)
    assert react.fr_div(p[:, perm]) == pytest.approx(div, rel=1e-12, abs=1e-15)
    assert react.fr_dvs(p[::-1]) == pytest.approx(dvs, rel=1e-12, abs=1e-15)
    assert div == pytest.approx(ref.fr_div(p), rel=1e-12, abs=1e-15)


# --- against the straightforward loops ----------------------------------------------------------------

@pytest.mark.parametrize("seed,size", [(10, dict(n=5, r=2, t=60)),
                                       pytest.param(11, dict(n=8, r=3, t=90), marks=pytest.mark.slow)])
def test_every_metric_matches_the_loop_reference(seed, size):
    p, listener, speaker, s = problem(seed, **size)
    p[1, 1, :, 3] = 0.3  # a constant channel
    fast = react.score(p, listener, speaker, s, reactions=None)
    slow = ref.score(p, listener, speaker, s)
    assert set(fast) == set(react.KEYS)
    for key in ("FRDist", "FRSyn", "FRSyn_all"):
        assert fast[key] == slow[key], key  # exact (DTW bit for bit; integer offsets, same float32 mean)
    for key in ("FRCorr", "FRDiv", "FRVar", "FRDvs"):
        assert fast[key] == pytest.approx(slow[key], rel=1e-12), key


def test_frdist_screen_does_not_change_the_value():
    p, listener, _, s = problem(12, n=8, r=2, t=40, density=0.9)
    p32 = p.astype(np.float32)
    (indptr, indices) = react.neighbour_lists(s)
    a = react.fr_dist_per_reaction(p32, listener.astype(np.float32), indptr, indices, screen=True)
    b = react.fr_dist_per_reaction(p32, listener.astype(np.float32), indptr, indices, screen=False)
    np.testing.assert_array_equal(a, b)


# --- errors -------------------------------------------------------------------------------------------

def test_errors_are_clear():
    p, listener, speaker, s = problem(13, r=10)
    s_bad = s.copy()
    s_bad[4] = 0
    with pytest.raises(InputError, match="row 4"):
        react.score(p, listener, speaker, s_bad)
    with pytest.raises(InputError, match="expected 10 reactions"):
        react.score(p[:, :3], listener, speaker, s)
    with pytest.raises(InputError, match="listener"):
        react.score(p, listener[:, :50], speaker, s)
    with pytest.raises(InputError, match="neighbours"):
        react.score(p, listener, speaker, s[:-1])
    with pytest.raises(InputError, match=r"predictions.*\(N, R, T, 25\)"):
        react.score(p[..., :24], listener, speaker, s)
    p_nan = p.copy()
    p_nan[2, 1, 5, 7] = np.nan
    with pytest.raises(InputError, match=r"NaN.*\(2, 1, 5, 7\)"):
        react.score(p_nan, listener, speaker, s)
