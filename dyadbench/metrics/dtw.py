"""Exact dynamic time warping (tslearn's ``dtw``), fast: SIMD lanes, strips, shared cost rows, float32 screen.

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
  pairs that share nothing (the screen's float64 pass below) are aligned LANES at a time with each
  lane's own series on both sides;
- **strips**: the grid is swept in column strips of :data:`STRIP` columns over all rows, so the strip of
  the lane series stays in the L1 cache; the right border of a strip is kept for the next one;
- **groups**: several dimension groups (REACT: AUs 0:15, valence/arousal 15:17, expressions 17:25), each
  with its own warping path, are aligned in the same sweep, :data:`FUSED` groups per recurrence loop so
  that their dependency chains overlap; a pair's value is ``0 + w_0 * dtw_0 + w_1 * dtw_1 + ...``
  (weights in order);
- **shared cost rows**: when at most half of a shared series' rows are distinct within a group (REACT's
  binary action-unit occurrences repeat), each distinct row's costs are computed once per strip and the
  repeated rows read them; the values are the same numbers, computed fewer times;
- **threads**: queries are spread over numba threads (``prange``).

Minimum over candidates with a certified float32 screen (:func:`min_weighted_dtw`): when every input
value is a float32 number (REACT's are) and small enough not to overflow, every pair is first aligned
by the same kernel in float32 (twice the SIMD lanes per register). Each float32 cost, sum and square root
rounds with relative error at most u = 2**-24, every term is non-negative and min is exact, so the float32
value v32 of a pair is within ``eps = (T1 + T2 + D + 4) u`` (relative) of the exact real DTW, and so is
the float64 value (with u = 2**-53); subnormal results add at most an absolute ``slack``. Hence with
``m = 4 eps`` the float64 value lies in ``[v32 (1 - m) - slack, v32 (1 + m) + slack]``. For each query
only the candidates whose lower end does not exceed the smallest upper end are recomputed in float64:
those include every candidate whose float64 value attains the minimum, so the minimum and the first
candidate attaining it are exactly those of computing every pair in float64. The screen changes the
running time only, never a result (tests compare both ways bit for bit).

Pruning (early abandoning, ``prune=True``): every warping path crosses each column j of the grid, and
along a path C never decreases (a non-negative cost added with rounding to nearest gives a result >=
the other operand; min returns one of its operands), so in the computed arithmetic itself
``C(T1-1, T2-1) >= min_i C(i, j)``. Evaluating the pair's value expression ``0 + sum_g w_g sqrt(.)`` on
these column minima (the right border of a finished strip) therefore gives a lower bound of the
computed value: sqrt, products with w_g >= 0 and sums are monotone. Each pass first aligns a query's
most promising candidates; its other candidates are abandoned (value inf) once their bound exceeds: in
float64, the smallest of those values (strictly: an abandoned candidate is strictly worse, so neither
the minimum nor the first candidate attaining it changes); in float32, their smallest screen upper
end, comparing the bound's screen lower end (an abandoned candidate would have been screened out
anyway, so the same candidates reach the float64 pass). The bound only helps when candidates differ
clearly: DTW without a window tolerates any time warp, so the prefix of the grid carries no more than
its share of the cost (on near ties every candidate is still aligned in full).
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange, set_num_threads, get_num_threads

from dyadbench.errors import InputError

LANES = 16
STRIP = 16
WIDTH = STRIP * LANES
FUSED = 3  # groups swept together in one recurrence loop (padded with zero-cost groups)
CHECK_EVERY = 4  # strips between two pruning checks (a check costs about 1/16 of a strip)
COARSE_FRAMES = 75  # frames of the subsampled series that order candidates for pruning
PRUNE_GAP = 0.25  # candidates ranked within this factor of a query's best are aligned in full first
PRUNE_MIN_SHARE = 0.1  # below this share of candidates left to prune, every candidate is aligned in one round


@njit(cache=True, nogil=True, inline="always")
def _strip_costs(x, i, strip, n, start, stop, costs, row):
    """costs[row, k] = 0 + sum_{d=start}^{stop-1} (x[i, d] - strip[d, k])**2 for k < n (dims in order).

    Groups are padded to a multiple of four dims with zeros in both series (see :func:`_pad_groups`):
    a padding dim adds 0 * 0 = +0.0 to a non-negative sum, which leaves it unchanged, so every pass
    takes four dims. The first pass starts from t0 * t0, which equals 0.0 + t0 * t0.
    """
    for d in range(start, stop, 4):
        xa = x[i, d]
        xb = x[i, d + 1]
        xc = x[i, d + 2]
        xd = x[i, d + 3]
        if d == start:
            for k in range(n):
                ta = xa - strip[d, k]
                tb = xb - strip[d + 1, k]
                tc = xc - strip[d + 2, k]
                td = xd - strip[d + 3, k]
                costs[row, k] = ((ta * ta + tb * tb) + tc * tc) + td * td
        else:
            for k in range(n):
                ta = xa - strip[d, k]
                tb = xb - strip[d + 1, k]
                tc = xc - strip[d + 2, k]
                td = xd - strip[d + 3, k]
                costs[row, k] = (((costs[row, k] + ta * ta) + tb * tb) + tc * tc) + td * td


@njit(cache=True, nogil=True, inline="always")
def _strip_costs_per_lane(xl, i, strip, n, start, stop, costs, row):
    """:func:`_strip_costs` with each lane's own shared frame: ``xl[d, i * LANES + b]`` replaces ``x[i, d]``
    in lane b (column k * LANES + b)."""
    for d in range(start, stop, 4):
        pa = xl[d, i * LANES:(i + 1) * LANES]
        pb = xl[d + 1, i * LANES:(i + 1) * LANES]
        pc = xl[d + 2, i * LANES:(i + 1) * LANES]
        pd = xl[d + 3, i * LANES:(i + 1) * LANES]
        sa = strip[d]
        sb = strip[d + 1]
        sc = strip[d + 2]
        sd = strip[d + 3]
        out = costs[row]
        for k in range(0, n, LANES):
            for b in range(LANES):
                ta = pa[b] - sa[k + b]
                tb = pb[b] - sb[k + b]
                tc = pc[b] - sc[k + b]
                td = pd[b] - sd[k + b]
                if d == start:
                    out[k + b] = ((ta * ta + tb * tb) + tc * tc) + td * td
                else:
                    out[k + b] = (((out[k + b] + ta * ta) + tb * tb) + tc * tc) + td * td


@njit(cache=True, nogil=True, inline="always")
def _sweep_rows(grid, costs, q0, p0, c0, q1, p1, c1, q2, p2, c2, n):
    """One grid row of FUSED groups: for each group, with its current grid row q, previous row p and cost
    row c (lane b of column k at ``k * LANES + b``, column -1 first in the grid rows)::

        grid[q, k + LANES] = costs[c, k] + min(grid[q, k], grid[p, k + LANES], grid[p, k])

    (left, up, diagonal). min is exact, so the order of the comparisons changes no value; the groups'
    chains are independent, which keeps the vector units busy while each waits on its left neighbour.
    """
    for k in range(n):
        u0 = grid[p0, k + LANES]
        u1 = grid[p1, k + LANES]
        u2 = grid[p2, k + LANES]
        d0 = grid[p0, k]
        d1 = grid[p1, k]
        d2 = grid[p2, k]
        m0 = u0 if u0 < d0 else d0
        m1 = u1 if u1 < d1 else d1
        m2 = u2 if u2 < d2 else d2
        l0 = grid[q0, k]
        l1 = grid[q1, k]
        l2 = grid[q2, k]
        grid[q0, k + LANES] = costs[c0, k] + (l0 if l0 < m0 else m0)
        grid[q1, k + LANES] = costs[c1, k] + (l1 if l1 < m1 else m1)
        grid[q2, k + LANES] = costs[c2, k] + (l2 if l2 < m2 else m2)


@njit(cache=True, nogil=True)
def _lower_bounds_exceed(bnd, t1, n_groups, weights, count, limits, scale, slack):
    """True when every lane b < count has ``(0 + sum_g w_g sqrt(min_i bnd[g, (i+1) LANES + b])) * scale - slack
    > limits[b]``: the right border of a strip holds C_g(i, j) of one column j, which every warping path
    crosses, and C only grows along a path (non-negative costs added with rounding to nearest), so this is
    the final value's expression evaluated on smaller arguments (see the module docstring, pruning)."""
    for b in range(count):
        value = 0.0
        for g in range(n_groups):
            low = bnd[g, LANES + b]
            for i in range(1, t1):
                c = bnd[g, (i + 1) * LANES + b]
                if c < low:
                    low = c
            value = value + weights[g] * np.sqrt(low)
        if not value * scale - slack > limits[b]:
            return False
    return True


@njit(cache=True, nogil=True)
def _align_lanes(x, xl, ys, gstart, gstop, weights, out, rep, rep_ptr, slot, limits, count, scale, slack):
    """Align the shared series ``x`` (T1, D) against the LANES series in ``ys`` (D, T2 * LANES); or, when
    ``xl`` is not empty, lane b's own series ``xl[:, t * LANES + b]`` (D, T1 * LANES) against lane b of
    ``ys`` (``x`` is then unused and nothing is tabulated).

    Rows of ``x`` that repeat within a group share one cost row: for group g, ``rep[rep_ptr[g]:rep_ptr[g+1]]``
    are the distinct rows whose costs are computed once per strip, and ``slot[g, i]`` is row i's entry
    among them (-1: group g is not tabulated, its costs are computed row by row). Same values either way.

    Writes ``out[b] = 0 + sum_g weights[g] * sqrt(C_g(T1-1, T2-1))`` for each lane b. The grid is
    computed in the dtype of ``x`` and ``ys`` (float64: exact; float32: the screen's approximation).

    Pruning: every :data:`CHECK_EVERY` strips, when the lower bound ``value * scale - slack`` of each of
    the first ``count`` lanes exceeds its ``limits[b]`` (:func:`_lower_bounds_exceed`), the alignment is
    abandoned and every ``out[b]`` is inf. With all limits inf nothing is checked.
    """
    per_lane = xl.shape[0] > 0
    t1 = xl.shape[1] // LANES if per_lane else x.shape[0]
    t2 = ys.shape[1] // LANES
    n_groups = gstart.shape[0]
    padded = -(-n_groups // FUSED) * FUSED
    n_rep = rep.shape[0]
    # bnd[g, (i + 1) * LANES + b] = C_g(i, j0 - 1) of lane b (left border of the current strip)
    bnd = np.full((padded, (t1 + 1) * LANES), np.inf, dtype=ys.dtype)
    bnd[:, :LANES] = 0.0
    grid = np.empty((2 * padded, (STRIP + 1) * LANES), dtype=ys.dtype)  # rows 2g + 0/1: previous/current
    costs = np.zeros((n_rep + padded, WIDTH), dtype=ys.dtype)  # padding groups keep their zero cost row
    strip = np.empty((ys.shape[0], WIDTH), dtype=ys.dtype)
    cost_of = np.empty(padded, dtype=np.int64)
    for g in range(n_groups, padded):
        cost_of[g] = n_rep + g
    prune = False
    for b in range(count):
        prune = prune or limits[b] < np.inf
    for j0 in range(0, t2, STRIP):
        if prune and j0 > 0 and (j0 // STRIP) % CHECK_EVERY == 0 and _lower_bounds_exceed(
                bnd, t1, n_groups, weights, count, limits, scale, slack):
            out[:] = np.inf
            return
        w = min(STRIP, t2 - j0)
        n = w * LANES
        for d in range(ys.shape[0]):
            for k in range(n):
                strip[d, k] = ys[d, j0 * LANES + k]
        for g in range(n_groups):
            for s in range(rep_ptr[g], rep_ptr[g + 1]):
                _strip_costs(x, rep[s], strip, n, gstart[g], gstop[g], costs, s)
        for g in range(padded):
            for b in range(LANES):
                grid[2 * g, b] = bnd[g, b]
            for k in range(LANES, n + LANES):
                grid[2 * g, k] = np.inf
        for i in range(t1):
            p = i & 1
            q = 1 - p
            base = (i + 1) * LANES
            for g in range(n_groups):
                s = -1 if per_lane else slot[g, i]
                if s < 0:
                    s = n_rep + g
                    if per_lane:
                        _strip_costs_per_lane(xl, i, strip, n, gstart[g], gstop[g], costs, s)
                    else:
                        _strip_costs(x, i, strip, n, gstart[g], gstop[g], costs, s)
                cost_of[g] = s
            for g in range(padded):
                for b in range(LANES):
                    grid[2 * g + q, b] = bnd[g, base + b]
            for g in range(0, padded, FUSED):
                _sweep_rows(grid, costs, 2 * g + q, 2 * g + p, cost_of[g], 2 * g + 2 + q, 2 * g + 2 + p,
                            cost_of[g + 1], 2 * g + 4 + q, 2 * g + 4 + p, cost_of[g + 2], n)
            for g in range(padded):
                for b in range(LANES):
                    bnd[g, base + b] = grid[2 * g + q, n + b]
        bnd[:, :LANES] = np.inf
    for b in range(LANES):
        value = 0.0
        for g in range(n_groups):
            value = value + weights[g] * np.sqrt(bnd[g, t1 * LANES + b])
        out[b] = value


@njit(cache=True, nogil=True)
def _interleave(series, idx, count, cols, ys):
    """ys[e, t * LANES + b] = series[idx[min(b, count - 1)], t, cols[e]] (in the dtype of ys), 0 where
    cols[e] < 0 (padding dims); missing lanes repeat the last series."""
    for b in range(LANES):
        s = series[idx[min(b, count - 1)]]
        for t in range(s.shape[0]):
            row = s[t]
            for e in range(cols.shape[0]):
                ys[e, t * LANES + b] = row[cols[e]] if cols[e] >= 0 else 0.0


@njit(cache=True, nogil=True)
def _pad_columns(x, cols):
    """x[:, cols] with zeros where cols < 0 (padding dims)."""
    out = np.zeros((x.shape[0], cols.shape[0]), dtype=x.dtype)
    for t in range(x.shape[0]):
        for e in range(cols.shape[0]):
            if cols[e] >= 0:
                out[t, e] = x[t, cols[e]]
    return out


@njit(cache=True, parallel=True)
def _batched_values(shared, lanes, pair_s, pair_l, batch_start, weights, rep, rep_ptr, slot, cols, pstart, pstop,
                    limits, scale, slack):
    """Value of each pair (shared[pair_s[p]], lanes[pair_l[p]]), computed LANES pairs at a time in the
    dtype of ``shared``.

    Pairs are sorted by ``pair_s``; batch b is ``batch_start[b]:batch_start[b+1]`` (one shared series,
    at most LANES pairs). ``rep``/``rep_ptr``/``slot``: the repeated rows of each shared series
    (:func:`_repeated_rows`); ``cols``/``pstart``/``pstop``: the groups' dims padded to multiples of four
    (:func:`_pad_groups`); ``limits``/``scale``/``slack``: pruning (:func:`_align_lanes`), per pair.
    """
    values = np.empty(pair_s.shape[0])
    for b in prange(batch_start.shape[0] - 1):
        first = batch_start[b]
        count = batch_start[b + 1] - first
        m = pair_s[first]
        ys = np.empty((cols.shape[0], lanes.shape[1] * LANES), dtype=shared.dtype)
        idx = np.empty(LANES, dtype=np.int64)
        out = np.empty(LANES)
        for lane in range(count):
            idx[lane] = pair_l[first + lane]
        _interleave(lanes, idx, count, cols, ys)
        ptr = rep_ptr[m]
        _align_lanes(_pad_columns(shared[m], cols), np.empty((0, 0), dtype=shared.dtype), ys, pstart, pstop,
                     weights, out, rep[ptr[0]:ptr[-1]], ptr - ptr[0], slot[m], limits[first:first + count], count,
                     scale, slack)
        for lane in range(count):
            values[first + lane] = out[lane]
    return values


@njit(cache=True, parallel=True)
def _paired_values(shared, lanes, pair_s, pair_l, weights, cols, pstart, pstop, limits, scale, slack):
    """Value of each pair (shared[pair_s[p]], lanes[pair_l[p]]), LANES consecutive pairs at a time with
    both series per lane: full lanes when the pairs share no series (the screen's float64 pass)."""
    values = np.empty(pair_s.shape[0])
    no_rep = np.zeros(0, dtype=np.int64)
    no_ptr = np.zeros(pstart.shape[0] + 1, dtype=np.int64)
    no_slot = np.zeros((pstart.shape[0], 0), dtype=np.int64)
    for b in prange((pair_s.shape[0] + LANES - 1) // LANES):
        first = b * LANES
        count = min(LANES, pair_s.shape[0] - first)
        xl = np.empty((cols.shape[0], shared.shape[1] * LANES), dtype=shared.dtype)
        ys = np.empty((cols.shape[0], lanes.shape[1] * LANES), dtype=shared.dtype)
        out = np.empty(LANES)
        _interleave(shared, pair_s[first:first + count], count, cols, xl)
        _interleave(lanes, pair_l[first:first + count], count, cols, ys)
        _align_lanes(np.empty((0, cols.shape[0]), dtype=shared.dtype), xl, ys, pstart, pstop, weights, out, no_rep,
                     no_ptr, no_slot, limits[first:first + count], count, scale, slack)
        for lane in range(count):
            values[first + lane] = out[lane]
    return values


def _pad_groups(gstart, gstop):
    """Each group's dims laid out contiguously and padded with zeros to a multiple of four.

    Returns ``cols`` (padded dim -> source dim, -1 for padding) and the groups' padded (start, stop).
    """
    cols, pstart, pstop = [], [], []
    for lo, hi in zip(gstart, gstop):
        pstart.append(len(cols))
        cols += list(range(lo, hi)) + [-1] * (-(hi - lo) % 4)
        pstop.append(len(cols))
    return (np.array(cols, dtype=np.int64), np.array(pstart, dtype=np.int64), np.array(pstop, dtype=np.int64))


def _repeated_rows(shared: np.ndarray, used: np.ndarray, gstart, gstop):
    """For each used shared series and group: its distinct rows, when at most half of the rows are distinct.

    Returns ``rep`` (flat row indices), ``rep_ptr`` (M, G + 1) (series m, group g: ``rep[rep_ptr[m, g]:
    rep_ptr[m, g + 1]]``) and ``slot`` (M, G, T) (row i of group g -> index within the series' block of
    ``rep``, or -1 when the group is computed row by row). Rows are compared by their bytes, so rows that
    are equal as numbers but differ in bytes (0.0 and -0.0) are merely not shared.
    """
    m_total, t, _ = shared.shape
    n_groups = len(gstart)
    slot = np.full((m_total, n_groups, t), -1, dtype=np.int64)
    rep_ptr = np.zeros((m_total, n_groups + 1), dtype=np.int64)
    reps, total = [], 0
    for m in np.unique(used):
        start = total
        for g, (lo, hi) in enumerate(zip(gstart, gstop)):
            rep_ptr[m, g] = total
            block = np.ascontiguousarray(shared[m, :, lo:hi])
            keys = block.view(np.dtype((np.void, block.itemsize * block.shape[1]))).ravel()
            _, first, inverse = np.unique(keys, return_index=True, return_inverse=True)
            if 2 * len(first) <= t:
                slot[m, g] = total - start + inverse.ravel()
                reps.append(first)
                total += len(first)
        rep_ptr[m, n_groups] = total
    rep = np.concatenate(reps).astype(np.int64) if reps else np.zeros(0, dtype=np.int64)
    return rep, rep_ptr, slot


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


def _values(shared, lanes, pair_s, pair_l, groups, limits=None, scale: float = 1.0, slack: float = 0.0) -> np.ndarray:
    """Values of the listed pairs, in the given pair order, computed in the dtype of ``shared``.

    Pairs are batched by shared series (one broadcast series, repeated rows tabulated) unless that
    would leave most lanes empty (pairs that share little, as in the screen's float64 pass); then
    LANES arbitrary pairs form a batch. The values are the same either way. With ``limits`` (per pair),
    a batch whose every pair has ``value * scale - slack`` certainly above its limit may be abandoned:
    those pairs get inf (:func:`_align_lanes`); every other value is unchanged.
    """
    if len(pair_s) == 0:
        return np.empty(0)
    limits = np.full(len(pair_s), np.inf) if limits is None else np.asarray(limits, dtype=np.float64)
    order = np.argsort(pair_s, kind="stable")
    batches = _batches(pair_s[order])
    values = np.empty(len(pair_s))
    cols, pstart, pstop = _pad_groups(*groups[:2])
    prune = (limits[order], float(scale), float(slack))
    if len(batches) - 1 > 2 * -(-len(pair_s) // LANES):
        values[order] = _paired_values(shared, lanes, pair_s[order], pair_l[order], groups[2], cols, pstart, pstop,
                                       *prune)
    else:
        values[order] = _batched_values(shared, lanes, pair_s[order], pair_l[order], batches, groups[2],
                                        *_repeated_rows(shared, pair_s, groups[0], groups[1]), cols, pstart, pstop,
                                        *prune)
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
    return _values(refs, queries, ri, qi, groups)


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


def _screen_margin(t1: int, t2: int, dims: int, weights: np.ndarray) -> tuple[float, float]:
    """(relative margin m, absolute slack) of the screen: the float64 value of a pair lies in
    ``[v32 (1 - m) - slack, v32 (1 + m) + slack]`` of its float32 value v32 (module docstring)."""
    eps = (t1 + t2 + dims + 4) * 2.0 ** -24
    # subnormal float32 results: each of the <= (t1 + t2) (dims + 3) operations on a path errs by at most
    # 2**-149 absolutely; the square root turns an absolute error e of a sum into at most sqrt(e)
    slack = 2 * max(1.0, float(weights.sum())) * np.sqrt((t1 + t2) * (dims + 3) * 2.0 ** -149)
    return 4 * eps, float(slack)


def _screen_bounds(approx, t1: int, t2: int, dims: int, weights: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Interval certain to hold the float64 value of each pair, from its float32 value (module docstring)."""
    margin, slack = _screen_margin(t1, t2, dims, weights)
    return approx * (1 - margin) - slack, approx * (1 + margin) + slack


def _float32_copies(queries: np.ndarray, refs: np.ndarray):
    """(queries, refs) as float32 when every value is a float32 number and no float32 grid sum can
    overflow; None when the screen does not apply."""
    copies = []
    for a in (queries, refs):
        a32 = a.astype(np.float32, copy=False)
        if a32 is not a and not np.array_equal(a32, a):
            return None
        copies.append(a32)
    largest = max(float(np.abs(queries).max(initial=0)), float(np.abs(refs).max(initial=0)))
    if (queries.shape[1] + refs.shape[1]) * queries.shape[2] * (2 * largest) ** 2 >= 1e37:
        return None
    return copies


def _coarse_values(queries, refs, indices, pair_q, groups) -> np.ndarray:
    """Cheap ordering key of each pair: its value on the series subsampled to about :data:`COARSE_FRAMES`
    frames, in float32 (about (T / COARSE_FRAMES)**2 times less work than the pair itself)."""
    coarse = [np.ascontiguousarray(a[:, ::max(1, -(-a.shape[1] // COARSE_FRAMES))], dtype=np.float32)
              for a in (queries, refs)]
    return _values(coarse[1], coarse[0], indices, pair_q, groups)


def _pruned_values(shared, lanes, pair_s, pair_l, groups, pairs, rank, limit_of=None, scale: float = 1.0,
                   slack: float = 0.0) -> np.ndarray:
    """Values of ``pairs`` (indices into the pair lists, whose lane series ``pair_l`` is the query); inf for
    the other pairs and for pairs that cannot attain their query's minimum.

    ``rank`` None: every listed pair is aligned in full. Otherwise, per query, the listed pairs whose
    ``rank`` is within a factor 1 + :data:`PRUNE_GAP` of the query's smallest are aligned in full first
    (near ties gain nothing from pruning; when fewer than :data:`PRUNE_MIN_SHARE` of the pairs remain,
    all are aligned in one round); the smallest of their values v sets the query's limit
    ``limit_of(v)`` (default v itself), and the query's other pairs are aligned with pruning against it
    (:func:`_values`): a pair is abandoned only when ``value * scale - slack`` certainly exceeds the limit.
    """
    values = np.full(len(pair_s), np.inf)
    if rank is None:
        values[pairs] = _values(shared, lanes, pair_s[pairs], pair_l[pairs], groups)
        return values
    queries = int(pair_l.max()) + 1
    lowest = np.full(queries, np.inf)
    np.minimum.at(lowest, pair_l[pairs], rank[pairs])
    near = rank[pairs] <= lowest[pair_l[pairs]] * (1 + PRUNE_GAP)
    if np.count_nonzero(~near) < PRUNE_MIN_SHARE * len(pairs):  # too few to gain from a second round
        values[pairs] = _values(shared, lanes, pair_s[pairs], pair_l[pairs], groups)
        return values
    first, rest = pairs[near], pairs[~near]
    values[first] = _values(shared, lanes, pair_s[first], pair_l[first], groups)
    best = np.full(queries, np.inf)
    np.minimum.at(best, pair_l[first], values[first])
    limits = best if limit_of is None else limit_of(best)
    values[rest] = _values(shared, lanes, pair_s[rest], pair_l[rest], groups, limits[pair_l[rest]], scale, slack)
    return values


def min_weighted_dtw(queries, refs, indptr, indices, groups=None, *, screen: bool = True, prune: bool = True,
                     threads: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """For each query q: the minimum over its candidates r of the weighted grouped DTW, and where.

    ``queries`` (Q, T1, D) float32/float64 and ``refs`` (M, T2, D), finite (no rounding is applied
    here); candidates of query q are ``indices[indptr[q]:indptr[q+1]]`` (CSR), each query needs at
    least one. Returns ``(values (Q,), position (Q,))`` where position is the index *within the
    candidate list* of the first candidate attaining the minimum.

    Work is batched by reference (one reference shared by LANES queries). With ``screen`` (default),
    when the inputs allow it, every pair is first aligned in float32 and only the candidates that can
    still attain a query's minimum are aligned in float64 (see the module docstring): the same values
    and positions as ``screen=False``, which aligns every pair in float64. With ``prune`` (default), each
    pass first aligns the most promising candidates of each query in full (:func:`_pruned_values`;
    float32 pass: ranked by their value on subsampled series; float64 pass: by their float32 value) and
    then abandons the others as soon as a lower bound shows they cannot attain the minimum (module
    docstring): again the same values and positions.
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
        copies = _float32_copies(queries, refs) if screen else None
        everything = np.arange(len(indices))
        rank = _coarse_values(queries, refs, indices, pair_q, groups) if prune else None
        if copies is not None:
            queries32, refs32 = copies
            margin, slack = _screen_margin(queries.shape[1], refs.shape[1], queries.shape[2], groups[2])
            approx = _pruned_values(refs32, queries32, indices, pair_q, groups, everything, rank,
                                    lambda v: v * (1 + margin) + slack, 1 - margin, slack)
            low, high = _screen_bounds(approx, queries.shape[1], refs.shape[1], queries.shape[2], groups[2])
            keep = np.flatnonzero(low <= np.minimum.reduceat(high, indptr[:-1])[pair_q])
            values = _pruned_values(refs, queries, indices, pair_q, groups, keep, approx if prune else None)
        else:
            values = _pruned_values(refs, queries, indices, pair_q, groups, everything, rank)
    finally:
        set_num_threads(previous)
    best = np.minimum.reduceat(values, indptr[:-1])
    hit = np.where(values == best[pair_q], position, np.iinfo(np.int64).max)
    return best, np.minimum.reduceat(hit, indptr[:-1])
