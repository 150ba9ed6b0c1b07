"""Exact dynamic time warping (tslearn's ``dtw``), fast: SIMD lanes, strips, threads and exact pruning.

Definition (identical to ``tslearn.metrics.dtw`` with default arguments: no window, the full
T1 x T2 grid)::

    c(i, j)  = sum_d (x[i, d] - y[j, d])**2              (dims summed in order, float64)
    C(i, j)  = c(i, j) + min(C(i-1, j), C(i, j-1), C(i-1, j-1)),   C(-1, -1) = 0, other borders inf
    dtw(x, y) = sqrt(C(T1-1, T2-1))

The kernel performs exactly these floating-point operations in exactly this order for every cell, so
its values equal tslearn's bit for bit (the tests check this); only the schedule differs:

- **lanes**: :data:`LANES` reference series are aligned against one query at once, one SIMD lane each
  (the query frame is shared by all lanes; the references are stored lane-interleaved);
- **strips**: the grid is swept in column strips of :data:`STRIP` columns over all rows, so the strip of
  the references stays in the L1 cache; the right border of a strip is kept for the next one;
- **groups**: several dimension groups (REACT: AUs 0:15, valence/arousal 15:17, expressions 17:25), each
  with its own warping path, are aligned in the same sweep; a pair's value is
  ``0 + w_0 * dtw_0 + w_1 * dtw_1 + ...`` (weights in order);
- **threads**: queries are spread over numba threads (``prange``).

Minimum over candidates with exact pruning (:func:`min_weighted_dtw`): every warping path crosses every
column, so after a strip ending at column j, ``m_g = min_i C_g(i, j)`` satisfies ``m_g <= C_g(T1-1, T2-1)``
exactly in floating point (each cell adds a non-negative cost to a minimum of its predecessors, and
rounding is monotone). Hence ``lb = 0 + w_0 sqrt(m_0) + ...`` never exceeds the pair's computed value.
A batch of lanes is abandoned only when every lane's ``lb`` is strictly greater than the best value
already found for that query, so the minimum (and the first index attaining it) is unchanged.
Candidates are tried in increasing order of their diagonal-path cost (an upper bound of DTW) so that a
good value is found early; the order affects the running time only, never the result.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange, set_num_threads, get_num_threads

from dyadbench.errors import InputError

LANES = 8
STRIP = 16


@njit(cache=True, nogil=True)
def _strip_bound(bnd, rows, lane, weights):
    """0 + sum_g w_g sqrt(min_i bnd[g, i]) for one lane: a lower bound of the lane's final value."""
    value = 0.0
    for g in range(bnd.shape[0]):
        low = np.inf
        for i in range(rows):
            c = bnd[g, (i + 1) * LANES + lane]
            if c < low:
                low = c
        value = value + weights[g] * np.sqrt(low)
    return value


@njit(cache=True, nogil=True)
def _align_lanes(x, ys, gstart, gstop, weights, threshold, out):
    """Align query ``x`` (T1, D) against the LANES references in ``ys`` (D, T2 * LANES).

    Writes ``out[b] = 0 + sum_g weights[g] * sqrt(C_g(T1-1, T2-1))`` for each lane b and returns False;
    returns True (``out`` untouched) when the batch was abandoned because every lane's lower bound
    exceeded ``threshold`` (pass inf to never abandon).
    """
    t1 = x.shape[0]
    t2 = ys.shape[1] // LANES
    n_groups = gstart.shape[0]
    width = STRIP * LANES
    # bnd[g, (i + 1) * LANES + b] = C_g(i, j0 - 1) of lane b (left border of the current strip)
    bnd = np.full((n_groups, (t1 + 1) * LANES), np.inf)
    bnd[:, :LANES] = 0.0
    prev = np.empty((n_groups, (STRIP + 1) * LANES))
    cur = np.empty((n_groups, (STRIP + 1) * LANES))
    cost = np.empty((n_groups, width))
    strip_y = np.empty((ys.shape[0], width))
    for j0 in range(0, t2, STRIP):
        w = min(STRIP, t2 - j0)
        n = w * LANES
        for d in range(ys.shape[0]):
            strip_y[d, :n] = ys[d, j0 * LANES:j0 * LANES + n]
        for g in range(n_groups):
            prev[g, :LANES] = bnd[g, :LANES]
            prev[g, LANES:] = np.inf
        for i in range(t1):
            xi = x[i]
            for g in range(n_groups):
                c = cost[g]
                d = gstart[g]
                stop = gstop[g]
                xv = xi[d]
                yr = strip_y[d]
                for k in range(n):
                    t = xv - yr[k]
                    c[k] = t * t  # == 0.0 + t * t
                d += 1
                while d + 1 < stop:  # two dims per pass: same operations, same order
                    xa = xi[d]
                    ya = strip_y[d]
                    xb = xi[d + 1]
                    yb = strip_y[d + 1]
                    for k in range(n):
                        ta = xa - ya[k]
                        tb = xb - yb[k]
                        c[k] = (c[k] + ta * ta) + tb * tb
                    d += 2
                if d < stop:
                    xv = xi[d]
                    yr = strip_y[d]
                    for k in range(n):
                        t = xv - yr[k]
                        c[k] += t * t
            base = (i + 1) * LANES
            for g in range(n_groups):
                q = cur[g]
                p = prev[g]
                c = cost[g]
                b_row = bnd[g]
                for b in range(LANES):
                    q[b] = b_row[base + b]
                for k in range(n):
                    left = q[k]
                    up = p[k + LANES]
                    diag = p[k]
                    m = left if left < up else up
                    m = m if m < diag else diag
                    q[k + LANES] = c[k] + m
                for b in range(LANES):
                    b_row[base + b] = q[n + b]
            prev, cur = cur, prev
        bnd[:, :LANES] = np.inf
        if threshold < np.inf and j0 + w < t2:
            alive = False
            for b in range(LANES):
                if _strip_bound(bnd, t1, b, weights) <= threshold:
                    alive = True
                    break
            if not alive:
                return True
    for b in range(LANES):
        value = 0.0
        for g in range(n_groups):
            value = value + weights[g] * np.sqrt(bnd[g, t1 * LANES + b])
        out[b] = value
    return False


@njit(cache=True, nogil=True)
def _interleave(refs_t, idx, count, ys):
    """ys[d, j * LANES + b] = refs_t[idx[min(b, count - 1)], d, j] (missing lanes repeat the last)."""
    for b in range(LANES):
        r = refs_t[idx[min(b, count - 1)]]
        for d in range(r.shape[0]):
            row = r[d]
            out = ys[d]
            for j in range(row.shape[0]):
                out[j * LANES + b] = row[j]


@njit(cache=True, nogil=True)
def _diagonal_bound(x, y, gstart, gstop, weights):
    """Weighted cost of the diagonal path (equal lengths): an upper bound used only for ordering."""
    value = 0.0
    for g in range(gstart.shape[0]):
        s = 0.0
        for t in range(x.shape[0]):
            for d in range(gstart[g], gstop[g]):
                diff = x[t, d] - y[d, t]
                s += diff * diff
        value += weights[g] * np.sqrt(s)
    return value


@njit(cache=True, parallel=True)
def _min_over_candidates(queries, refs_t, indptr, indices, gstart, gstop, weights, prune):
    n_queries = queries.shape[0]
    best = np.full(n_queries, np.inf)
    best_at = np.full(n_queries, -1, dtype=np.int64)
    same_length = queries.shape[1] == refs_t.shape[2]
    for q in prange(n_queries):
        x = queries[q]
        cands = indices[indptr[q]:indptr[q + 1]]
        n_cands = cands.shape[0]
        order = np.arange(n_cands)
        if prune and same_length and n_cands > LANES:
            ub = np.empty(n_cands)
            for c in range(n_cands):
                ub[c] = _diagonal_bound(x, refs_t[cands[c]], gstart, gstop, weights)
            order = np.argsort(ub, kind="mergesort")
        ys = np.empty((refs_t.shape[1], refs_t.shape[2] * LANES))
        out = np.empty(LANES)
        idx = np.empty(LANES, dtype=np.int64)
        pos = np.empty(LANES, dtype=np.int64)
        for start in range(0, n_cands, LANES):
            count = min(LANES, n_cands - start)
            for b in range(count):
                pos[b] = order[start + b]
                idx[b] = cands[pos[b]]
            _interleave(refs_t, idx, count, ys)
            threshold = best[q] if prune else np.inf
            if _align_lanes(x, ys, gstart, gstop, weights, threshold, out):
                continue
            for b in range(count):
                v = out[b]
                # strictly smaller, or equal at an earlier candidate position: the first minimum wins
                if v < best[q] or (v == best[q] and pos[b] < best_at[q]):
                    best[q] = v
                    best_at[q] = pos[b]
    return best, best_at


@njit(cache=True, parallel=True)
def _pair_values(queries, refs_t, qi, ri, gstart, gstop, weights):
    n_pairs = qi.shape[0]
    values = np.empty(n_pairs)
    n_batches = (n_pairs + LANES - 1) // LANES
    for bi in prange(n_batches):
        ys = np.empty((refs_t.shape[1], refs_t.shape[2] * LANES))
        out = np.empty(LANES)
        idx = np.empty(LANES, dtype=np.int64)
        start = bi * LANES
        # one query per batch: split the batch where the query changes
        s = start
        stop = min(start + LANES, n_pairs)
        while s < stop:
            e = s
            while e < stop and qi[e] == qi[s]:
                e += 1
            count = e - s
            for b in range(count):
                idx[b] = ri[s + b]
            _interleave(refs_t, idx, count, ys)
            _align_lanes(queries[qi[s]], ys, gstart, gstop, weights, np.inf, out)
            for b in range(count):
                values[s + b] = out[b]
            s = e
    return values


# --- public API ------------------------------------------------------------------------------------

def _as_series(a, name: str) -> np.ndarray:
    a = np.asarray(a, dtype=np.float64)
    if a.ndim == 1:
        a = a[:, None]
    if a.ndim != 2 or a.shape[0] == 0:
        raise InputError(name, f"expected a (T, d) time series with T >= 1, got shape {a.shape}")
    if not np.isfinite(a).all():
        raise InputError(name, f"contains {int(np.size(a) - np.isfinite(a).sum())} NaN/inf values")
    return a


def _groups(groups, dim: int, name: str = "groups") -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(start, stop, weight) triples -> arrays; each group must be a non-empty slice of the dims."""
    if groups is None:
        groups = [(0, dim, 1.0)]
    starts, stops, weights = [], [], []
    for start, stop, weight in groups:
        if not 0 <= start < stop <= dim:
            raise InputError(name, f"group {start}:{stop} is not a non-empty slice of {dim} dims")
        if not weight >= 0:
            raise InputError(name, f"group {start}:{stop} has weight {weight}; weights must be >= 0")
        starts.append(int(start))
        stops.append(int(stop))
        weights.append(float(weight))
    return (np.array(starts, dtype=np.int64), np.array(stops, dtype=np.int64), np.array(weights))


def _transposed(refs: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(np.transpose(refs, (0, 2, 1)))


def weighted_dtw_pairs(queries: np.ndarray, refs: np.ndarray, query_index, ref_index, groups=None) -> np.ndarray:
    """Value of every listed pair: ``0 + sum_g w_g * dtw(queries[q][:, g], refs[r][:, g])``.

    ``queries`` (Q, T1, D), ``refs`` (M, T2, D), float64 (no rounding is applied here);
    ``query_index``/``ref_index`` (P,) pair lists; ``groups`` a list of (start, stop, weight), default
    one group of all dims with weight 1 (then the value is the plain DTW).
    """
    queries = np.ascontiguousarray(queries, dtype=np.float64)
    refs = np.ascontiguousarray(refs, dtype=np.float64)
    qi = np.asarray(query_index, dtype=np.int64)
    ri = np.asarray(ref_index, dtype=np.int64)
    if qi.shape != ri.shape or qi.ndim != 1:
        raise InputError("pairs", f"query and reference index lists differ: {qi.shape} vs {ri.shape}")
    if queries.ndim != 3 or refs.ndim != 3 or queries.shape[2] != refs.shape[2]:
        raise InputError("series", f"expected (Q, T1, D) and (M, T2, D), got {queries.shape} and {refs.shape}")
    if len(qi) and (qi.min() < 0 or qi.max() >= len(queries) or ri.min() < 0 or ri.max() >= len(refs)):
        raise InputError("pairs", "an index is out of range")
    order = np.argsort(qi, kind="stable")
    gstart, gstop, weights = _groups(groups, queries.shape[2])
    values = np.empty(len(qi))
    values[order] = _pair_values(queries, _transposed(refs), qi[order], ri[order], gstart, gstop, weights)
    return values


def dtw(x, y) -> float:
    """DTW between two series (T1, d) and (T2, d) (1-d input is one channel), as ``tslearn.metrics.dtw``.

    .. math:: \\mathrm{DTW}(x, y) = \\sqrt{\\min_{\\pi} \\sum_{(i,j)\\in\\pi} \\lVert x_i - y_j\\rVert^2}

    over monotone, continuous warping paths from (0, 0) to (T1-1, T2-1); no window. Lower means more
    similar; 0 for identical series. NaN/inf values raise :class:`InputError` (tslearn would instead
    drop trailing NaN frames).
    """
    x = _as_series(x, "x")
    y = _as_series(y, "y")
    if x.shape[1] != y.shape[1]:
        raise InputError("y", f"has {y.shape[1]} dims per frame, x has {x.shape[1]}")
    return float(weighted_dtw_pairs(x[None], y[None], [0], [0])[0])


def min_weighted_dtw(queries, refs, indptr, indices, groups=None, *, prune: bool = True,
                     threads: int | None = None, transposed: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """For each query q: the minimum over its candidates r of the weighted grouped DTW, and where.

    ``queries`` (Q, T1, D) and ``refs`` (M, T2, D) float64, finite (no rounding is applied here);
    candidates of query q are ``indices[indptr[q]:indptr[q+1]]`` (CSR), each query needs at least one.
    Returns ``(values (Q,), position (Q,))`` where position is the index *within the candidate list* of
    the first candidate attaining the minimum. ``prune`` enables the exact abandoning described in the
    module docstring (same results, less work). ``threads`` caps numba's threads for this call.
    ``transposed=True``: ``refs`` is given as (M, D, T2) (saves the transposition over repeated calls).
    """
    queries = np.ascontiguousarray(queries, dtype=np.float64)
    refs = np.ascontiguousarray(refs, dtype=np.float64)
    refs_t = refs if transposed else _transposed(refs)
    indptr = np.asarray(indptr, dtype=np.int64)
    indices = np.asarray(indices, dtype=np.int64)
    if queries.ndim != 3 or refs_t.ndim != 3 or queries.shape[2] != refs_t.shape[1]:
        raise InputError("series", f"expected (Q, T1, D) and (M, T2, D), got {queries.shape} and {refs.shape}")
    if indptr.shape != (len(queries) + 1,) or indptr[0] != 0 or indptr[-1] != len(indices):
        raise InputError("candidates", "indptr must have Q + 1 entries from 0 to len(indices)")
    empty = np.flatnonzero(np.diff(indptr) <= 0)
    if len(empty):
        raise InputError("candidates", f"query {int(empty[0])} has no candidate")
    if len(indices) and (indices.min() < 0 or indices.max() >= len(refs)):
        raise InputError("candidates", "a candidate index is out of range")
    gstart, gstop, weights = _groups(groups, queries.shape[2])
    previous = get_num_threads()
    if threads is not None:
        set_num_threads(max(1, min(int(threads), previous)))
    try:
        return _min_over_candidates(queries, refs_t, indptr, indices, gstart, gstop, weights, bool(prune))
    finally:
        set_num_threads(previous)
