"""Straightforward loop implementations of the REACT metrics, written from the specification.

They follow the structure of the official scripts (one pair at a time, tslearn's ``dtw`` per pair and
group, ``np.cov`` / ``np.corrcoef`` per channel, torch for FRSyn's float32 mean and argmax) and serve as
the reference that the fast implementation is checked against (tests) and timed against (benchmark).
Inputs are rounded to float32 first, as in the official pipeline.
"""

from __future__ import annotations

import numpy as np
import torch
from tslearn.metrics import dtw as tslearn_dtw

GROUPS = ((0, 15, 1 / 15), (15, 17, 1.0), (17, 25, 1 / 8))


def _f32(a):
    return np.asarray(a, dtype=np.float32).astype(np.float64)


def ccc(y_true, y_pred) -> float:
    values = []
    for c in range(y_true.shape[1]):
        x, y = y_true[:, c], y_pred[:, c]
        if np.all(x == x[0]) or np.all(y == y[0]):
            cor = 0.0
        else:
            cov = np.cov(x, y)
            cor = cov[0, 1] / np.sqrt(cov[0, 0]) / np.sqrt(cov[1, 1])
            cor = min(max(cor, -1.0), 1.0)
        numerator = 2 * cor * np.std(x) * np.std(y)
        denominator = np.var(x) + np.var(y) + (np.mean(x) - np.mean(y)) ** 2
        values.append(numerator / (denominator + 1e-8))
    return float(np.mean(values))


def neighbours_of(s, k):
    return np.argwhere(s[k] == 1).reshape(-1)


def _best_over_neighbours(pred, listener, s, pair_value, best) -> float:
    """mean over k of sum over i of best(pair_value(...) over the neighbours j of k)."""
    pred, listener = _f32(pred), _f32(listener)
    per_k = []
    for k in range(pred.shape[0]):
        total = 0
        for i in range(pred.shape[1]):
            total += best(pair_value(pred[k, i], listener[j]) for j in neighbours_of(s, k))
        per_k.append(total)
    return float(np.mean(per_k))


def fr_corr(pred, listener, s) -> float:
    return _best_over_neighbours(pred, listener, s, lambda p, lst: ccc(lst, p), max)


def grouped_dtw(a, b) -> float:
    res = 0
    for st, ed, weight in GROUPS:
        res += weight * tslearn_dtw(a[:, st:ed], b[:, st:ed])
    return res


def fr_dist(pred, listener, s) -> float:
    return _best_over_neighbours(pred, listener, s, grouped_dtw, min)


def fr_div(pred) -> float:
    pred = _f32(pred)
    n, r, t, d = pred.shape
    if r == 1:
        return 0.0
    per_k = []
    for k in range(n):
        total = 0.0
        for i in range(r):
            for j in range(r):
                if i != j:
                    total += np.sum((pred[k, i] - pred[k, j]) ** 2)
        per_k.append(total / (r * (r - 1) * t * d))
    return float(np.mean(per_k))


def fr_var(pred) -> float:
    pred = _f32(pred)
    values = [np.var(pred[k, i, :, c], ddof=1) for k in range(pred.shape[0]) for i in range(pred.shape[1])
              for c in range(pred.shape[3])]
    return float(np.mean(values))


def fr_dvs(pred) -> float:
    pred = _f32(pred)
    n, r, t, d = pred.shape
    total = 0.0
    for i in range(r):
        for k in range(n):
            for l in range(n):
                if k != l:
                    total += np.sum((pred[k, i] - pred[l, i]) ** 2)
    return total / (n * (n - 1) * r) / (t * d)


def _shift(x, y, lag):
    if lag > 0:
        return x[lag:], y[:-lag]
    if lag < 0:
        return x[:lag], y[-lag:]
    return x, y


def tlcc_offset(pred, speaker) -> int:
    curve = []
    for lag in range(-49, 50):
        pcc = []
        for c in range(pred.shape[1]):
            a, b = _shift(pred[:, c], speaker[:, c], lag)
            if np.all(a == a[0]) or np.all(b == b[0]):
                pcc.append(float("nan"))
            else:
                pcc.append(np.corrcoef(a, b)[0, 1].item())
        curve.append(torch.mean(torch.Tensor(pcc)))
    return abs(49 - int(torch.argmax(torch.Tensor(curve))))


def fr_syn(pred, speaker, all_reactions=False) -> float:
    pred, speaker = _f32(pred), _f32(speaker)
    reactions = range(pred.shape[1]) if all_reactions else [0]
    offsets = [tlcc_offset(pred[k, i], speaker[k]) for k in range(pred.shape[0]) for i in reactions]
    return torch.mean(torch.Tensor(offsets)).item()


def score(pred, listener, speaker, s) -> dict[str, float]:
    return {"FRCorr": fr_corr(pred, listener, s), "FRDist": fr_dist(pred, listener, s),
            "FRDiv": fr_div(pred), "FRVar": fr_var(pred), "FRDvs": fr_dvs(pred),
            "FRSyn": fr_syn(pred, speaker), "FRSyn_all": fr_syn(pred, speaker, all_reactions=True)}
