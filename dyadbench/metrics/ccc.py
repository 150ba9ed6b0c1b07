"""Concordance correlation coefficient (CCC) as REACT's FRCorr uses it, and its fast max over neighbours.

Per channel, for a ground-truth channel x and a predicted channel y of length T (REACT's
``concordance_correlation_coefficient(y_true, y_pred)``)::

    r   = cov1(x, y) / sd1(x) / sd1(y)        (np.cov, ddof=1; 0 when x or y is constant), clipped to [-1, 1]
    ccc = 2 r sd(x) sd(y) / (var(x) + var(y) + (mean(x) - mean(y))**2 + 1e-8)   (ddof=0)

and the series' value is the plain mean over channels. A constant channel therefore contributes 0, so
a perfect copy scores below 1 when some channel is constant. CCC is in [-1, 1]; higher is better.

"Constant" is decided exactly (all values equal). The reference's ``np.cov`` gives NaN (then 0) for
a constant channel only when the channel mean is exact; otherwise it divides two round-off residues.
dyadbench always uses 0, as the specification states.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

CCC_EPS = 1e-8


def series_stats(a: np.ndarray) -> dict[str, np.ndarray]:
    """Per-channel statistics over the time axis (-2) of ``a`` (..., T, C), float64."""
    a = np.asarray(a, dtype=np.float64)
    n = a.shape[-2]
    mean = a.mean(axis=-2)
    centred = a - mean[..., None, :]
    ss = np.sum(centred * centred, axis=-2)
    constant = np.all(a == a[..., :1, :], axis=-2)
    return {"centred": centred, "mean": mean, "var": ss / n, "sd": np.sqrt(ss / n),
            "sd1": np.sqrt(ss / (n - 1)), "constant": constant}


def _ccc_from(cross: np.ndarray, gt: dict, pred: dict, n: int) -> np.ndarray:
    """Per-channel CCC from the centred cross products ``cross`` = sum_t xc * yc."""
    with np.errstate(invalid="ignore", divide="ignore"):
        r = (cross / (n - 1)) / gt["sd1"] / pred["sd1"]
    r = np.where(gt["constant"] | pred["constant"], 0.0, r)
    r = np.clip(r, -1.0, 1.0)
    numerator = 2 * r * gt["sd"] * pred["sd"]
    denominator = gt["var"] + pred["var"] + (gt["mean"] - pred["mean"]) ** 2
    return numerator / (denominator + CCC_EPS)


def ccc_channels(gt: np.ndarray, pred: np.ndarray) -> np.ndarray:
    """Per-channel CCC (C,) of two (T, C) series (``gt`` plays y_true). T >= 2."""
    gs, ps = series_stats(gt), series_stats(pred)
    cross = np.sum(gs["centred"] * ps["centred"], axis=0)
    return _ccc_from(cross, gs, ps, gs["centred"].shape[0])


def ccc(gt: np.ndarray, pred: np.ndarray) -> float:
    """Mean over channels of :func:`ccc_channels` (higher is better, in [-1, 1]).

    .. math:: \\mathrm{CCC}(x, y) = \\frac{1}{C}\\sum_c
              \\frac{2 r_c \\sigma_{x_c} \\sigma_{y_c}}{\\sigma_{x_c}^2 + \\sigma_{y_c}^2
              + (\\mu_{x_c} - \\mu_{y_c})^2 + 10^{-8}}
    """
    return float(np.mean(ccc_channels(gt, pred)))


@njit(cache=True, parallel=True)
def _max_ccc_kernel(p_c, p_mean, p_var, p_sd, p_sd1, p_const,
                    l_c, l_mean, l_var, l_sd, l_sd1, l_const, indptr, indices):
    n_rows, n_pred, t_len, n_ch = p_c.shape
    best = np.full((n_rows, n_pred), -np.inf)
    for k in prange(n_rows):
        cross = np.empty((n_pred, n_ch))
        for jj in range(indptr[k], indptr[k + 1]):
            j = indices[jj]
            cross[:, :] = 0.0
            for t in range(t_len):
                lt = l_c[j, t]
                for i in range(n_pred):
                    pt = p_c[k, i, t]
                    for c in range(n_ch):
                        cross[i, c] += pt[c] * lt[c]
            for i in range(n_pred):
                total = 0.0
                for c in range(n_ch):
                    if l_const[j, c] or p_const[k, i, c]:
                        r = 0.0
                    else:
                        r = (cross[i, c] / (t_len - 1)) / l_sd1[j, c] / p_sd1[k, i, c]
                        r = min(max(r, -1.0), 1.0)
                    dm = l_mean[j, c] - p_mean[k, i, c]
                    numerator = 2 * r * l_sd[j, c] * p_sd[k, i, c]
                    total += numerator / (l_var[j, c] + p_var[k, i, c] + dm * dm + 1e-8)
                value = total / n_ch
                if value > best[k, i]:
                    best[k, i] = value
    return best


def max_ccc_over_neighbours(predictions: np.ndarray, listener: np.ndarray | dict, indptr: np.ndarray,
                            indices: np.ndarray) -> np.ndarray:
    """(N, R) array: for row k and prediction i, max over neighbours j of CCC(listener[j], predictions[k, i]).

    ``predictions`` (N, R, T, C), ``listener`` (M, T, C) or its :func:`series_stats` (to reuse them over
    several calls); neighbours of row k are ``indices[indptr[k]:indptr[k+1]]`` (each row needs at least
    one; checked by the caller).
    """
    ps = series_stats(predictions)
    ls = listener if isinstance(listener, dict) else series_stats(listener)
    return _max_ccc_kernel(ps["centred"], ps["mean"], ps["var"], ps["sd"], ps["sd1"], ps["constant"],
                           ls["centred"], ls["mean"], ls["var"], ls["sd"], ls["sd1"], ls["constant"],
                           np.asarray(indptr, dtype=np.int64), np.asarray(indices, dtype=np.int64))
