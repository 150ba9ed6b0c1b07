"""Pruned minimum over candidates (early-abandoned DTW): never a different value or position.

References: tslearn's ``dtw`` per pair and group (``tests/react_reference.py``) and the unpruned kernel.
Series are longer than CHECK_EVERY * STRIP frames so that the pruning checks run.
"""

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st
from hypothesis.extra.numpy import arrays

import react_reference as ref
from dyadbench.metrics import react
from dyadbench.metrics.dtw import (CHECK_EVERY, LANES, STRIP, _groups, _pruned_values, _screen_margin, _values,
                                   min_weighted_dtw)

GROUPS = ref.GROUPS
T = CHECK_EVERY * STRIP + 37  # two pruning checks per alignment


def reference_min(queries, refs, lists):
    """(min, first argmin) per query from tslearn, one pair at a time."""
    best, where = [], []
    for q, cands in enumerate(lists):
        values = [ref.grouped_dtw(queries[q].astype(np.float64), refs[j].astype(np.float64)) for j in cands]
        best.append(min(values))
        where.append(values.index(min(values)))
    return np.array(best), np.array(where)


def adversarial(seed):
    """Float32 REACT-like series: binary AUs, a constant channel, exact duplicates, a query equal to a
    candidate (value 0), near ties one ulp apart, and queries far from every candidate."""
    rng = np.random.default_rng(seed)
    refs = rng.random((2 * LANES + 4, T, 25)).astype(np.float32)
    refs[:, :, :15] = rng.random((len(refs), T, 15)) < 0.2
    refs[:, :, 16] = 0.25  # a constant channel
    refs[3] = refs[9]  # identical neighbours: the first one must be reported
    refs[11] = refs[9]
    refs[12] = refs[9]
    refs[12, 40, 20] = np.nextafter(refs[9, 40, 20], np.float32(2))  # one ulp away
    queries = np.stack([refs[9], refs[9] + np.float32(0.01), refs[20] * np.float32(0.5),
                        np.full((T, 25), 0.5, np.float32), refs[30][::-1].copy()])
    lists = [list(range(len(refs))), [12, 11, 9, 3, 0, 1, 2], list(range(len(refs)))[::-1], [5, 6],
             list(range(0, len(refs), 2))]
    indptr = np.cumsum([0] + [len(c) for c in lists])
    return queries, refs, lists, indptr, np.concatenate(lists)


@pytest.mark.parametrize("screen", [True, False])
@pytest.mark.parametrize("seed", [0, 1])
def test_pruned_minimum_equals_tslearn_on_adversarial_cases(screen, seed):
    queries, refs, lists, indptr, indices = adversarial(seed)
    values, where = min_weighted_dtw(queries, refs, indptr, indices, GROUPS, screen=screen, prune=True)
    expected, first = reference_min(queries, refs, lists)
    np.testing.assert_array_equal(values, expected)
    np.testing.assert_array_equal(where, first)
    assert values[0] == 0.0 and where[0] == lists[0].index(3)  # duplicates of the query: the first one
    unpruned = min_weighted_dtw(queries, refs, indptr, indices, GROUPS, screen=screen, prune=False)
    np.testing.assert_array_equal(values, unpruned[0])
    np.testing.assert_array_equal(where, unpruned[1])


def test_pruning_abandons_only_pairs_worse_than_the_limit():
    # float64 pass: a query equal to one candidate (value 0) abandons the clearly worse ones
    queries, refs, lists, indptr, indices = adversarial(2)
    groups = _groups(GROUPS, 25)
    pair_q = np.repeat(np.arange(len(queries)), np.diff(indptr))
    refs64, queries64 = refs.astype(np.float64), queries.astype(np.float64)
    full = _values(refs64, queries64, indices, pair_q, groups)
    rank = np.arange(1, len(indices) + 1, dtype=np.float64)
    rank[indices == 9] = 0.0  # candidate 9 leads alone: equal to query 0, so query 0's limit is 0
    pairs = np.flatnonzero(pair_q <= 1)  # queries 0 and 1 (a batch is abandoned when all its lanes are)
    pruned = _pruned_values(refs64, queries64, indices, pair_q, groups, pairs, rank)
    abandoned = np.isinf(pruned[pairs])
    assert abandoned.sum() >= LANES // 2  # the pruning did run (a batch of LANES pairs goes together)
    lead = np.array([full[(pair_q == q) & (indices == 9)][0] for q in range(2)])
    assert (full[pairs][abandoned] > lead[pair_q[pairs][abandoned]]).all()
    np.testing.assert_array_equal(pruned[pairs][~abandoned], full[pairs][~abandoned])
    assert np.isinf(np.delete(pruned, pairs)).all()  # unlisted pairs


series = arrays(np.float32, st.tuples(st.just(T), st.just(5)),
                elements=st.one_of(st.floats(0, 1, width=32), st.sampled_from([0.0, 1.0])))


@settings(max_examples=25, deadline=None)
@given(series, series, st.floats(0, 2), st.booleans())
def test_abandoned_pair_exceeds_its_limit(x, y, fraction, float32):
    # one pair, limit = fraction * its value: abandoned only when its (screen) lower end is above the limit
    groups = _groups([(0, 2, 0.5), (2, 5, 1.0)], 5)
    one = np.array([0])
    shared, lanes = (y[None], x[None]) if float32 else (y[None].astype(np.float64), x[None].astype(np.float64))
    value = _values(shared, lanes, one, one, groups)[0]
    margin, slack = _screen_margin(T, T, 5, groups[2]) if float32 else (0.0, 0.0)
    limit = fraction * value
    pruned = _values(shared, lanes, one, one, groups, np.array([limit]), 1 - margin, slack)[0]
    if np.isinf(pruned):
        assert value * (1 - margin) - slack > limit
    else:
        assert pruned == value


def test_frdist_pruned_equals_the_loops():
    # REACT shape with R = 3, identical neighbours and ground-truth predictions (one candidate at 0)
    rng = np.random.default_rng(7)
    n, r = 5, 3
    listener = rng.random((n, T, 25)).astype(np.float32)
    listener[:, :, :15] = rng.random((n, T, 15)) < 0.3
    listener[4] = listener[1]
    speaker = rng.random((n, T, 25)).astype(np.float32)
    pred = rng.random((n, r, T, 25)).astype(np.float32)
    pred[:, 0] = listener
    pred[2, 1] = listener[4]
    s = (rng.random((n, n)) < 0.6).astype(np.int64)
    np.fill_diagonal(s, 1)
    s[:, 4] = 1
    p, lst, _, (indptr, indices) = react.check_inputs(pred, listener, speaker, s, reactions=None)
    fast = react.fr_dist(p, lst, indptr, indices, prune=True)
    assert fast == ref.fr_dist(pred, listener, s)
    assert fast == react.fr_dist(p, lst, indptr, indices, prune=False, screen=False)
