"""Exact dynamic time warping (tslearn's ``dtw``), fast: SIMD lanes, strips, threads and exact pruning.

Definition (identical to ``tslearn.metrics.dtw`` with default arguments: no window, the full
T1 x T2 grid)::

    c(i, j)  = sum_d (x[i, d] - y[j, d])**2              (dims summed in order, float64)
    C(i, j)  = c(i, j) + min(C(i-1, j), C(i, j-1), C(i-1, j-1)),   C(-1, -1) = 0, other borders inf
    dtw(x, y) = sqrt(C(T1-1, T2-1))

The kernel performs exactly these floating-point operations in exactly this order for every cell, so
its values equal tslearn's bit for bit (the tests check this); only the schedule differs:

- **lanes**: :data:`LANES` pairs that share one series are aligned at once, one SIMD lane each (the
  shared series' frame is broadcast; the other series are stored lane-interleaved). DTW is symmetric
  operation for operation (the transposed grid adds the same costs to the same minima), so pairs are
  grouped by whichever side they share, e.g. all queries that have a given reference as candidate;
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
Each query's candidate with the smallest diagonal-path cost (an upper bound of DTW) is computed first;
every other pair then carries that value as its lane's threshold, and a batch is abandoned only when
every lane's ``lb`` is strictly greater than its threshold, so the minimum (and the first candidate
attaining it) is unchanged. The order of the work affects the running time only, never the result.
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
def _align_lanes(x, ys, gstart, gstop, weights, thresholds, out):
    """Align the shared series ``x`` (T1, D) against the LANES series in ``ys`` (D, T2 * LANES).

    Writes ``out[b] = 0 + sum_g weights[g] * sqrt(C_g(T1-1, T2-1))`` for each lane b and returns False;
    returns True (``out`` untouched) when the batch was abandoned because every lane's lower bound
    exceeded its ``thresholds[b]`` (inf: never abandon).
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
                while d + 3 < stop:  # four dims per pass: same operations, same order
                    xa = xi[d]
                    ya = strip_y[d]
                    xb = xi[d + 1]
                    yb = strip_y[d + 1]
                    xc = xi[d + 2]
                    yc = strip_y[d + 2]
                    xd = xi[d + 3]
                    yd = strip_y[d + 3]
                    for k in range(n):
                        ta = xa - ya[k]
                        tb = xb - yb[k]
                        tc = xc - yc[k]
                        td = xd - yd[k]
                        c[k] = (((c[k] + ta * ta) + tb * tb) + tc * tc) + td * td
                    d += 4
                while d < stop:
                    xv = xi[d]
                    yr = strip_y[d]
                    for k in range(n):
                        t = xv - yr[k]
                        c[k] += t * t
                    d += 1
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
        if j0 + w < t2:
            alive = False
            for b in range(LANES):
                if thresholds[b] == np.inf or _strip_bound(bnd, t1, b, weights) <= thresholds[b]:
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
def _interleave(series, idx, count, ys):
    """ys[d, t * LANES + b] = series[idx[min(b, count - 1)], t, d] as float64 (missing lanes repeat the last)."""
    for b in range(LANES):
        s = series[idx[min(b, count - 1)]]
        for t in range(s.shape[0]):
            row = s[t]
            for d in range(row.shape[0]):
                ys[d, t * LANES + b] = row[d]


@njit(cache=True, parallel=True)
def _diagonal_bounds(shared, lanes, pair_s, pair_l, gstart, gstop, weights):
    """Weighted cost of the diagonal path of every pair (equal lengths): an upper bound of its value,
    used only to order the work."""
    out = np.empty(pair_s.shape[0])
    for p in prange(pair_s.shape[0]):
        x = shared[pair_s[p]]
        y = lanes[pair_l[p]]
        value = 0.0
        for g in range(gstart.shape[0]):
            acc = 0.0
            for t in range(x.shape[0]):
                for d in range(gstart[g], gstop[g]):
                    diff = x[t, d] - y[t, d]
                    acc += diff * diff
            value += weights[g] * np.sqrt(acc)
        out[p] = value
    return out


@njit(cache=True, parallel=True)
def _batched_values(shared, lanes, pair_s, pair_l, thresholds, batch_start, gstart, gstop, weights):
    """Value of each pair (shared[pair_s[p]], lanes[pair_l[p]]), computed LANES pairs at a time.

    Pairs are sorted by ``pair_s``; batch b is ``batch_start[b]:batch_start[b+1]`` (one shared series,
    at most LANES pairs). A batch whose every lane exceeds its threshold is abandoned: its values are inf.
    """
    values = np.full(pair_s.shape[0], np.inf)
    for b in prange(batch_start.shape[0] - 1):
        first = batch_start[b]
        count = batch_start[b + 1] - first
        ys = np.empty((lanes.shape[2], lanes.shape[1] * LANES))
        idx = np.empty(LANES, dtype=np.int64)
        limit = np.full(LANES, np.inf)
        out = np.empty(LANES)
        for lane in range(count):
            idx[lane] = pair_l[first + lane]
            limit[lane] = thresholds[first + lane]
        for lane in range(count, LANES):
            limit[lane] = -np.inf  # padding lanes never keep a batch alive
        _interleave(lanes, idx, count, ys)
        if not _align_lanes(shared[pair_s[first]], ys, gstart, gstop, weights, limit, out):
            for lane in range(count):
                values[first + lane] = out[lane]
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


def _batches(sorted_shared: np.ndarray) -> np.ndarray:
    """Batch boundaries over pairs sorted by shared index: runs of one shared series, LANES at a time."""
    n = len(sorted_shared)
    change = np.flatnonzero(np.diff(sorted_shared)) + 1
    runs = zip(np.concatenate([[0], change]), np.concatenate([change, [n]]))
    return np.concatenate([np.arange(a, b, LANES) for a, b in runs] + [[n]]).astype(np.int64)


def _values(shared, lanes, pair_s, pair_l, thresholds, order_key, groups) -> np.ndarray:
    """Values of the listed pairs (inf where abandoned), in the given pair order."""
    if len(pair_s) == 0:
        return np.empty(0)
    order = np.lexsort((order_key, pair_s))
    values = np.empty(len(pair_s))
    values[order] = _batched_values(shared, lanes, pair_s[order], pair_l[order], thresholds[order],
                                    _batches(pair_s[order]), *groups)
    return values


def _check_series(queries, refs) -> tuple[np.ndarray, np.ndarray]:
    queries = np.ascontiguousarray(queries)
    refs = np.ascontiguousarray(refs, dtype=np.float64)
    if queries.ndim != 3 or refs.ndim != 3 or queries.shape[2] != refs.shape[2]:
        raise InputError("series", f"expected (Q, T1, D) and (M, T2, D), got {queries.shape} and {refs.shape}")
    if queries.dtype not in (np.float32, np.float64):
        queries = queries.astype(np.float64)
    return queries, refs


def weighted_dtw_pairs(queries: np.ndarray, refs: np.ndarray, query_index, ref_index, groups=None) -> np.ndarray:
    """Value of every listed pair: ``0 + sum_g w_g * dtw(queries[q][:, g], refs[r][:, g])``.

    ``queries`` (Q, T1, D) float32/float64 and ``refs`` (M, T2, D) (no rounding is applied here);
    ``query_index``/``ref_index`` (P,) pair lists; ``groups`` a list of (start, stop, weight), default
    one group of all dims with weight 1 (then the value is the plain DTW).
    """
    queries, refs = _check_series(queries, refs)
    qi = np.asarray(query_index, dtype=np.int64)
    ri = np.asarray(ref_index, dtype=np.int64)
    if qi.shape != ri.shape or qi.ndim != 1:
        raise InputError("pairs", f"query and reference index lists differ: {qi.shape} vs {ri.shape}")
    if len(qi) and (qi.min() < 0 or qi.max() >= len(queries) or ri.min() < 0 or ri.max() >= len(refs)):
        raise InputError("pairs", "an index is out of range")
    groups = _groups(groups, queries.shape[2])
    # DTW is symmetric operation for operation, so the reference can be the shared series of a batch
    return _values(refs, queries, ri, qi, np.full(len(qi), np.inf), np.zeros(len(qi)), groups)


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


def min_weighted_dtw(queries, refs, indptr, indices, groups=None, *, prune: bool = False,
                     threads: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """For each query q: the minimum over its candidates r of the weighted grouped DTW, and where.

    ``queries`` (Q, T1, D) float32/float64 and ``refs`` (M, T2, D), finite (no rounding is applied
    here); candidates of query q are ``indices[indptr[q]:indptr[q+1]]`` (CSR), each query needs at
    least one. Returns ``(values (Q,), position (Q,))`` where position is the index *within the
    candidate list* of the first candidate attaining the minimum.

    Work is batched by reference (one reference shared by LANES queries). With ``prune``, each query's
    candidate of smallest diagonal-path cost is computed first; every other pair then carries its
    query's value as a threshold and batches are abandoned exactly as the module docstring describes
    (same results; less work only when candidates differ clearly, else the extra first pass costs more).
    ``threads`` caps numba's threads for this call.
    """
    queries, refs = _check_series(queries, refs)
    indptr = np.asarray(indptr, dtype=np.int64)
    indices = np.asarray(indices, dtype=np.int64)
    if indptr.shape != (len(queries) + 1,) or indptr[0] != 0 or indptr[-1] != len(indices):
        raise InputError("candidates", "indptr must have Q + 1 entries from 0 to len(indices)")
    counts = np.diff(indptr)
    empty = np.flatnonzero(counts <= 0)
    if len(empty):
        raise InputError("candidates", f"query {int(empty[0])} has no candidate")
    if len(indices) and (indices.min() < 0 or indices.max() >= len(refs)):
        raise InputError("candidates", "a candidate index is out of range")
    groups = _groups(groups, queries.shape[2])
    pair_q = np.repeat(np.arange(len(queries)), counts)
    position = np.arange(len(indices)) - indptr[pair_q]
    previous = get_num_threads()
    if threads is not None:
        set_num_threads(max(1, min(int(threads), previous)))
    try:
        values = np.full(len(indices), np.inf)
        if prune:
            equal_lengths = queries.shape[1] == refs.shape[1]
            ub = (_diagonal_bounds(refs, queries, indices, pair_q, *groups) if equal_lengths
                  else np.zeros(len(indices)))
            by_bound = np.lexsort((position, ub, pair_q))
            first = by_bound[np.concatenate([[0], np.flatnonzero(np.diff(pair_q[by_bound])) + 1])]
            values[first] = _values(refs, queries, indices[first], pair_q[first], np.full(len(first), np.inf),
                                    np.zeros(len(first)), groups)
            rest = np.setdiff1d(np.arange(len(indices)), first)
            limit = values[first][pair_q[rest]]  # first holds one pair per query, in query order
            # hopeless pairs (diagonal bound far above the query's value) share batches: more abandoning
            with np.errstate(divide="ignore", invalid="ignore"):
                hopeless = np.nan_to_num(-ub[rest] / limit)
            values[rest] = _values(refs, queries, indices[rest], pair_q[rest], limit, hopeless, groups)
        else:
            values = _values(refs, queries, indices, pair_q, values, np.zeros(len(indices)), groups)
    finally:
        set_num_threads(previous)
    best = np.minimum.reduceat(values, indptr[:-1])
    hit = np.where(values == best[pair_q], position, np.iinfo(np.int64).max)
    return best, np.minimum.reduceat(hit, indptr[:-1])
