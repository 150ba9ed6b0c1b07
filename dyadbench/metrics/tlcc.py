"""Time-lagged cross-correlation offsets: REACT's FRSyn ("TLCC").

For a prediction x and the speaker y, both (T, C), and every lag in -MAX_LAG..MAX_LAG (99 lags at
25 fps: ``range(-int(2 * 25 - 1), int(2 * 25))``)::

    lag > 0: pair x[lag:] with y[:-lag];   lag < 0: pair x[:lag] with y[-lag:];   lag = 0: x with y
    r_c(lag) = Pearson correlation of channel c of the pair (np.corrcoef), NaN when a segment is constant
    R(lag)   = float32 mean over channels of float32(r_c(lag))  (NaN if any channel is NaN)
    offset   = |MAX_LAG - argmax_lag R|, argmax = the first NaN if any, else the first maximum

as the reference computes it (``np.corrcoef`` in float64, then ``torch.mean`` / ``torch.argmax`` of a
float32 tensor; torch is used here for those two steps so that float32 rounding and tie-breaking are
the same). A constant prediction gives NaN at every lag, hence argmax 0 and offset = MAX_LAG = 49.
Lower offsets are better (prediction and speaker synchronised).

"Constant" is decided exactly (all values of the segment equal), as the specification states; the
reference's ``np.corrcoef`` returns NaN there only when the segment mean is exact.
"""

from __future__ import annotations

import numpy as np
import torch
from numba import njit, prange

SECONDS = 2
FPS = 25
MAX_LAG = int(SECONDS * FPS - 1)
LAGS = np.arange(-MAX_LAG, MAX_LAG + 1)
CHUNK = 1024


@njit(cache=True, nogil=True)
def _run_end(v):
    """end[t] = first index u > t with v[u] != v[t] (len(v) if none)."""
    n = v.shape[0]
    end = np.empty(n, dtype=np.int64)
    end[n - 1] = n
    for t in range(n - 2, -1, -1):
        end[t] = end[t + 1] if v[t + 1] == v[t] else t + 1
    return end


@njit(cache=True, nogil=True)
def _pearson(a, a0, b, b0, n):
    """np.corrcoef(a[a0:a0+n], b[b0:b0+n])[0, 1] for non-constant segments."""
    sa = 0.0
    sb = 0.0
    for t in range(n):
        sa += a[a0 + t]
        sb += b[b0 + t]
    ma = sa / n
    mb = sb / n
    saa = 0.0
    sbb = 0.0
    sab = 0.0
    for t in range(n):
        da = a[a0 + t] - ma
        db = b[b0 + t] - mb
        saa += da * da
        sbb += db * db
        sab += da * db
    r = (sab / (n - 1)) / np.sqrt(saa / (n - 1)) / np.sqrt(sbb / (n - 1))
    return min(max(r, -1.0), 1.0)


@njit(cache=True, parallel=True)
def _lagged_correlations(x, y, max_lag):
    """r[m, lag + max_lag, c] for predictions x (M, T, C) and speakers y (M, T, C); NaN when constant."""
    n_items, t_len, n_ch = x.shape
    n_lags = 2 * max_lag + 1
    out = np.empty((n_items, n_lags, n_ch))
    for m in prange(n_items):
        for c in range(n_ch):
            xv = np.ascontiguousarray(x[m, :, c])
            yv = np.ascontiguousarray(y[m, :, c])
            x_end = _run_end(xv)
            y_end = _run_end(yv)
            for li in range(n_lags):
                lag = li - max_lag
                if lag >= 0:
                    x0, y0, n = lag, 0, t_len - lag
                else:
                    x0, y0, n = 0, -lag, t_len + lag
                if n < 2 or x_end[x0] >= x0 + n or y_end[y0] >= y0 + n:
                    out[m, li, c] = np.nan
                else:
                    out[m, li, c] = _pearson(xv, x0, yv, y0, n)
    return out


def lagged_correlations(pred: np.ndarray, speaker: np.ndarray) -> np.ndarray:
    """(M, 99, C) float64 per-channel correlations at each lag (see module docstring)."""
    return _lagged_correlations(np.ascontiguousarray(pred, dtype=np.float64),
                                np.ascontiguousarray(speaker, dtype=np.float64), MAX_LAG)


def offsets_from_correlations(r: np.ndarray) -> np.ndarray:
    """|MAX_LAG - argmax| per item from (M, 99, C) correlations, with the reference's float32 steps."""
    curves = torch.from_numpy(np.ascontiguousarray(r.astype(np.float32))).mean(dim=-1)
    return np.abs(MAX_LAG - torch.argmax(curves, dim=-1).numpy()).astype(np.int64)


def tlcc_offsets(pred: np.ndarray, speaker: np.ndarray, speaker_index: np.ndarray | None = None) -> np.ndarray:
    """Offsets (M,) in frames of predictions (M, T, C) against their speakers: ``speaker`` (M, T, C), or
    (S, T, C) with ``speaker_index`` (M,) naming each prediction's speaker (no copy of repeated speakers)."""
    index = np.arange(len(pred)) if speaker_index is None else np.asarray(speaker_index)
    out = np.empty(len(pred), dtype=np.int64)
    for start in range(0, len(pred), CHUNK):
        stop = start + CHUNK
        out[start:stop] = offsets_from_correlations(lagged_correlations(pred[start:stop], speaker[index[start:stop]]))
    return out


def float32_mean(values: np.ndarray) -> float:
    """``torch.mean(torch.Tensor(values)).item()``: the reference's float32 average of the offsets."""
    return float(torch.tensor(np.asarray(values), dtype=torch.float32).mean().item())
