"""How much keyframe placement can pay on a window: a model-free oracle for SFMS's central claim.

Reconstruct a window w (T, d) from k of its own frames by piecewise-linear interpolation, holding the
first keyframe before it and the last one after it:

.. math:: \\hat w_t = w_a + \\frac{t - a}{b - a}(w_b - w_a) \\quad (a \\le t \\le b \\text{ consecutive keyframes}),
          \\qquad \\mathrm{MSE}(P) = \\frac{1}{T d} \\sum_t \\lVert \\hat w_t - w_t \\rVert^2 .

:func:`interpolation_mse` scores given positions P (e.g. the static i·⌊T/k⌋); :func:`optimal_placement_mse`
finds min over all k-subsets exactly by dynamic programming over the last keyframe,
D_1(a) = head(a), D_m(b) = min_{a<b} D_{m−1}(a) + E(a, b), result min_b D_k(b) + tail(b), with E(a, b) the
interior error of the segment and head/tail the held ends. No quantiser and no network are involved,
so the ratio static / optimal is what placement alone can give on the data.

Per-channel allocation (each channel c its own k positions P_c, the same keyframe budget of k values
per channel): :func:`per_channel_optimal_mse` = (1/(T d)) Σ_c min_{P_c} SSE_c(P_c), each channel's own
dynamic programme; it can never exceed the shared optimum, whose one P serves every channel.
"""

from __future__ import annotations

import numba
import numpy as np


@numba.njit(cache=True)
def _segment_errors(w: np.ndarray) -> np.ndarray:
    t_len, dim = w.shape
    err = np.zeros((t_len, t_len))
    for a in range(t_len):
        for b in range(a + 2, t_len):
            e = 0.0
            for t in range(a + 1, b):
                alpha = (t - a) / (b - a)
                for j in range(dim):
                    v = w[a, j] + alpha * (w[b, j] - w[a, j]) - w[t, j]
                    e += v * v
            err[a, b] = e
    return err


@numba.njit(cache=True)
def _held_errors(w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    t_len, dim = w.shape
    head, tail = np.zeros(t_len), np.zeros(t_len)
    for a in range(t_len):
        for t in range(t_len):
            e = 0.0
            for j in range(dim):
                v = w[a, j] - w[t, j]
                e += v * v
            if t < a:
                head[a] += e
            elif t > a:
                tail[a] += e
    return head, tail


@numba.njit(cache=True)
def _optimal_programme(w: np.ndarray, k: int) -> tuple[float, np.ndarray]:
    """The smallest squared error of a piecewise-linear reconstruction through k frames (held at both ends) by
    dynamic programming over the last chosen frame, and the positions of one minimiser (first minimum on ties)."""
    t_len = w.shape[0]
    seg = _segment_errors(w)
    head, tail = _held_errors(w)
    cost = head.copy()
    parent = np.full((k, t_len), -1, dtype=np.int64)
    for m in range(1, k):
        nxt = np.full(t_len, np.inf)
        for b in range(t_len):
            for a in range(b):
                v = cost[a] + seg[a, b]
                if v < nxt[b]:
                    nxt[b] = v
                    parent[m, b] = a
        cost = nxt
    best, last = np.inf, -1
    for b in range(t_len):
        if cost[b] + tail[b] < best:
            best, last = cost[b] + tail[b], b
    out = np.empty(k, dtype=np.int64)
    for m in range(k - 1, -1, -1):
        out[m] = last
        last = parent[m, last]
    return best, out


def _check(window: np.ndarray, k: int) -> np.ndarray:
    w = np.asarray(window, dtype=np.float64)
    if w.ndim != 2 or not 1 <= k <= w.shape[0]:
        raise ValueError(f"need a (T, d) window and 1 <= k <= T, got shape {w.shape} and k = {k}")
    return w


def interpolation_mse(window: np.ndarray, positions: np.ndarray) -> float:
    """MSE of the piecewise-linear reconstruction through the frames at ``positions`` (held at both ends)."""
    pos = np.unique(np.asarray(positions, dtype=np.int64))
    w = _check(window, len(pos))
    if pos[0] < 0 or pos[-1] >= w.shape[0]:
        raise ValueError(f"positions must lie in [0, {w.shape[0]}), got {pos.tolist()}")
    t = np.arange(w.shape[0])
    rec = np.stack([np.interp(t, pos, w[pos, j]) for j in range(w.shape[1])], axis=1)
    return float(np.mean((rec - w) ** 2))


def optimal_placement_mse(window: np.ndarray, k: int) -> float:
    """The smallest :func:`interpolation_mse` over every set of ``k`` positions (exact)."""
    w = _check(window, k)
    return float(_optimal_programme(np.ascontiguousarray(w), k)[0] / w.size)


def optimal_positions(window: np.ndarray, k: int) -> np.ndarray:
    """Ascending positions of a k-set reaching :func:`optimal_placement_mse` (the first minimum found)."""
    w = _check(window, k)
    return _optimal_programme(np.ascontiguousarray(w), k)[1]


def per_channel_optimal_mse(window: np.ndarray, k: int) -> float:
    """The smallest :func:`interpolation_mse` when every channel places its own ``k`` positions (exact)."""
    w = _check(window, k)
    return float(sum(_optimal_programme(np.ascontiguousarray(w[:, c: c + 1]), k)[0] for c in range(w.shape[1]))
                 / w.size)
