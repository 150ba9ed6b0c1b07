"""Exact DTW: brute-force recurrence, tslearn equality, weighted groups, shared cost rows, the float32 screen."""

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st
from hypothesis.extra.numpy import arrays
from tslearn.metrics import dtw as tslearn_dtw

from dyadbench.errors import InputError
from dyadbench.metrics.dtw import (LANES, STRIP, _groups, _repeated_rows, _float32_copies, _screen_bounds, _values, dtw,
                                   min_weighted_dtw, weighted_dtw_pairs)

GROUPS = ((0, 15, 1 / 15), (15, 17, 1.0), (17, 25, 1 / 8))


def brute_force_dtw(x, y):
    """The recurrence written out on a full (T1+1, T2+1) matrix."""
    x, y = np.atleast_2d(x.T).T, np.atleast_2d(y.T).T
    acc = np.full((len(x) + 1, len(y) + 1), np.inf)
    acc[0, 0] = 0.0
    for i in range(len(x)):
        for j in range(len(y)):
            cost = 0.0
            for d in range(x.shape[1]):
                cost += (x[i, d] - y[j, d]) ** 2
            acc[i + 1, j + 1] = cost + min(acc[i, j + 1], acc[i + 1, j], acc[i, j])
    return float(np.sqrt(acc[-1, -1]))


def test_hand_computed_case():
    # x = [0, 1, 2], y = [0, 2]: best path (0,0) (1,0)|(1,1) (2,1): costs 0 + 1 + 0 -> sqrt(1)
    assert dtw(np.array([0.0, 1.0, 2.0]), np.array([0.0, 2.0])) == 1.0
    # a time-stretched copy aligns at zero cost
    assert dtw(np.array([1.0, 1.0, 2.0, 3.0, 3.0]), np.array([1.0, 2.0, 3.0])) == 0.0


@pytest.mark.parametrize("t1,t2,d", [(1, 1, 1), (1, 4, 2), (5, 1, 3), (6, 9, 2), (STRIP + 3, 2 * STRIP + 1, 4),
                                     (17, 17, 25)])
def test_equals_brute_force_recurrence(t1, t2, d):
    rng = np.random.default_rng(t1 * 100 + t2)
    x, y = rng.normal(size=(t1, d)), rng.normal(size=(t2, d))
    assert dtw(x, y) == brute_force_dtw(x, y)


def test_equals_tslearn_bit_for_bit_on_random_cases():
    rng = np.random.default_rng(0)
    for _ in range(20):
        t1, t2, d = rng.integers(1, 60), rng.integers(1, 60), rng.integers(1, 16)
        x = rng.random((t1, d)).astype(np.float32).astype(np.float64)
        y = rng.random((t2, d)).astype(np.float32).astype(np.float64)
        assert dtw(x, y) == tslearn_dtw(x, y)


def test_identical_series_is_zero():
    x = np.random.default_rng(1).normal(size=(40, 7))
    assert dtw(x, x) == 0.0


def test_weighted_pairs_match_group_sums():
    rng = np.random.default_rng(2)
    queries, refs = rng.random((3, 30, 25)), rng.random((5, 41, 25))
    qi, ri = [2, 0, 1, 0, 2, 2, 1, 0, 0, 1, 2], [4, 0, 3, 1, 1, 0, 2, 4, 2, 0, 3]
    values = weighted_dtw_pairs(queries, refs, qi, ri, GROUPS)
    for v, q, r in zip(values, qi, ri):
        expected = 0
        for s, e, w in GROUPS:
            expected += w * tslearn_dtw(queries[q][:, s:e], refs[r][:, s:e])
        assert v == expected


def test_repeated_reference_rows_share_cost_rows_with_identical_values():
    # binary action units repeat (REACT's AU occurrences): their cost rows are tabulated once per strip
    rng = np.random.default_rng(5)
    t = 3 * STRIP + 5
    refs = rng.random((4, t, 25))
    patterns = rng.integers(0, 2, size=(3, 15)).astype(np.float64)
    refs[:, :, :15] = patterns[rng.integers(0, 3, size=(4, t))]
    refs[1, ::2, :15] = -0.0 * refs[1, ::2, :15]  # 0.0 and -0.0: equal values, different bytes
    refs[2, :, 15:17] = refs[2, 0, 15:17]  # a constant group: one distinct row
    queries = rng.random((LANES + 3, t + 2, 25)).astype(np.float32)
    rep, rep_ptr, slot = _repeated_rows(refs, np.arange(4), np.array([0, 15, 17]), np.array([15, 17, 25]))
    assert (slot[:, 0] >= 0).all() and (slot[2, 1] >= 0).all() and (slot[:, 2] < 0).all()
    qi, ri = np.repeat(np.arange(len(queries)), 4), np.tile(np.arange(4), len(queries))
    values = weighted_dtw_pairs(queries, refs, qi, ri, GROUPS)
    for v, q, r in zip(values, qi, ri):
        expected = 0
        for s, e, w in GROUPS:
            expected += w * tslearn_dtw(queries[q][:, s:e].astype(np.float64), refs[r][:, s:e])
        assert v == expected


@pytest.mark.parametrize("screen", [True, False])
@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_min_over_candidates_is_exact(screen, dtype):
    rng = np.random.default_rng(3)
    n_refs = 3 * LANES
    queries, refs = rng.random((4, 35, 25)).astype(dtype), rng.random((n_refs, 35, 25)).astype(dtype)
    refs[7] = queries[1] + 0.01  # a clearly best candidate for query 1
    lists = [[0, 1, 2], list(range(3, 3 + 2 * LANES + 3)), [n_refs - 1], list(range(n_refs))[::-1]]
    indptr = np.cumsum([0] + [len(c) for c in lists])
    values, where = min_weighted_dtw(queries, refs, indptr, np.concatenate(lists), GROUPS, screen=screen)
    for q, cands in enumerate(lists):
        all_values = weighted_dtw_pairs(queries, refs, [q] * len(cands), cands, GROUPS)
        assert values[q] == all_values.min()
        assert where[q] == int(np.argmin(all_values))


def test_screen_keeps_near_ties_and_the_first_minimum():
    # candidates one float32 ulp apart differ far below the screen's margin: all must be recomputed exactly
    rng = np.random.default_rng(4)
    refs = rng.random((3 * LANES, 30, 25)).astype(np.float32)
    for j in range(LANES, 2 * LANES):
        refs[j] = refs[5]
        refs[j, j % 30, j % 25] = np.nextafter(refs[5, j % 30, j % 25], np.float32(2))
    refs[2 * LANES + 1] = refs[5]  # an exact duplicate: equal values at positions 5 and 2L+1
    queries = np.stack([refs[5] + np.float32(0.001), refs[LANES + 3] - np.float32(0.002)])
    indptr = np.array([0, len(refs), 2 * len(refs)])
    cand = np.tile(np.arange(len(refs)), 2)
    screened = min_weighted_dtw(queries, refs, indptr, cand, GROUPS, screen=True)
    plain = min_weighted_dtw(queries, refs, indptr, cand, GROUPS, screen=False)
    np.testing.assert_array_equal(screened[0], plain[0])
    np.testing.assert_array_equal(screened[1], plain[1])


float32_series = arrays(np.float32, st.tuples(st.integers(1, 40), st.just(5)),
                        elements=st.one_of(st.floats(-4, 4, width=32), st.floats(-2.0 ** -66, 2.0 ** -66, width=32),
                                           st.floats(-1e6, 1e6, width=32)))


@settings(max_examples=40, deadline=None)
@given(float32_series, float32_series)
def test_screen_interval_holds_the_float64_value(x, y):
    # the float32 alignment's certified interval contains the exact (float64) value, tiny values included
    groups = _groups([(0, 2, 0.5), (2, 5, 1.0)], 5)
    exact = _values(y[None].astype(np.float64), x[None], np.array([0]), np.array([0]), groups)
    approx = _values(y[None], x[None], np.array([0]), np.array([0]), groups)
    low, high = _screen_bounds(approx, len(x), len(y), 5, groups[2])
    assert low[0] <= exact[0] <= high[0]


def test_screen_needs_float32_values():
    assert _float32_copies(np.zeros((1, 3, 2), np.float32), np.full((1, 3, 2), 0.5)) is not None
    assert _float32_copies(np.zeros((1, 3, 2), np.float32), np.full((1, 3, 2), 0.1)) is None  # 0.1: no float32
    assert _float32_copies(np.full((1, 3, 2), 1e19, np.float32), np.zeros((1, 3, 2))) is None  # squares overflow


def test_bad_input_is_named():
    with pytest.raises(InputError, match="NaN"):
        dtw(np.array([[0.0], [np.nan]]), np.zeros((3, 1)))
    with pytest.raises(InputError, match="dims"):
        dtw(np.zeros((3, 2)), np.zeros((3, 1)))
    with pytest.raises(InputError, match="query 1 has no candidate"):
        min_weighted_dtw(np.zeros((2, 4, 3)), np.zeros((2, 4, 3)), [0, 1, 1], [0])


series = arrays(np.float64, st.tuples(st.integers(1, 12), st.integers(1, 4)),
                elements=st.floats(-10, 10, allow_nan=False, width=32))


@settings(max_examples=40, deadline=None)
@given(series, st.data())
def test_properties(x, data):
    y = data.draw(arrays(np.float64, st.tuples(st.integers(1, 12), st.just(x.shape[1])),
                         elements=st.floats(-10, 10, allow_nan=False, width=32)))
    value = dtw(x, y)
    assert value >= 0.0
    assert value == dtw(y, x)  # the transposed grid performs the same operations
    assert dtw(x, x) == 0.0
    if len(x) == len(y):  # the diagonal path is one warping path
        assert value <= np.sqrt(np.sum((x - y) ** 2)) * (1 + 1e-12)
    assert value == pytest.approx(brute_force_dtw(x, y), rel=1e-12, abs=1e-12)  # same path, other summation order
