"""Exact DTW: brute-force recurrence, tslearn equality, weighted groups, exact pruning, properties."""

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st
from hypothesis.extra.numpy import arrays
from tslearn.metrics import dtw as tslearn_dtw

from dyadbench.errors import InputError
from dyadbench.metrics.dtw import LANES, STRIP, dtw, min_weighted_dtw, weighted_dtw_pairs

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


@pytest.mark.parametrize("prune", [True, False])
def test_min_over_candidates_is_exact(prune):
    rng = np.random.default_rng(3)
    queries, refs = rng.random((4, 35, 25)), rng.random((30, 35, 25))
    refs[7] = queries[1] + 0.01  # a clearly best candidate for query 1
    lists = [[0, 1, 2], list(range(3, 3 + 2 * LANES + 3)), [29], list(range(30))[::-1]]
    indptr = np.cumsum([0] + [len(c) for c in lists])
    values, where = min_weighted_dtw(queries, refs, indptr, np.concatenate(lists), GROUPS, prune=prune)
    for q, cands in enumerate(lists):
        all_values = weighted_dtw_pairs(queries, refs, [q] * len(cands), cands, GROUPS)
        assert values[q] == all_values.min()
        assert where[q] == int(np.argmin(all_values))


def test_pruning_keeps_the_first_minimum_among_ties():
    rng = np.random.default_rng(4)
    refs = rng.random((3 * LANES, 20, 25))
    refs[2 * LANES + 1] = refs[5]  # duplicated candidate: equal values at positions 5 and 2L+1
    queries = refs[5:6] + 0.001
    indptr = np.array([0, len(refs)])
    values, where = min_weighted_dtw(queries, refs, indptr, np.arange(len(refs)), GROUPS, prune=True)
    assert where[0] == 5


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
    assert value == brute_force_dtw(x, y)
