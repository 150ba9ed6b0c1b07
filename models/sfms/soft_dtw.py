"""Soft dynamic time warping (Cuturi & Blondel) and its divergence, batched, differentiable.

sdtw_γ(x, y) = R[n, m] with R[i, j] = (x_i − y_j)² + softmin_γ(R[i−1, j−1], R[i−1, j], R[i, j−1]),
R[0, 0] = 0, R[i, 0] = R[0, j] = +∞, softmin_γ(a) = −γ log Σ exp(−a/γ).
Divergence: D_γ(x, y) = sdtw_γ(x, y) − ½ sdtw_γ(x, x) − ½ sdtw_γ(y, y) (0 when x = y, ≥ 0).
Sequences here are short (the predictor's 8 future frames), so a plain O(n·m) loop is used.
"""

from __future__ import annotations

import torch

_INF = 1e10


def soft_dtw(x: torch.Tensor, y: torch.Tensor, gamma: float) -> torch.Tensor:
    """sdtw_γ of scalar sequences x (B, n), y (B, m) with squared-difference cost: (B,)."""
    cost = (x[:, :, None] - y[:, None, :]).pow(2)
    n, m = cost.shape[1], cost.shape[2]
    inf = x.new_full((x.shape[0],), _INF)
    prev = [x.new_zeros(x.shape[0])] + [inf] * m  # row i−1 of R, columns 0..m
    for i in range(1, n + 1):
        row = [inf]
        for j in range(1, m + 1):
            stacked = torch.stack([prev[j - 1], prev[j], row[j - 1]], dim=-1)
            row.append(cost[:, i - 1, j - 1] - gamma * torch.logsumexp(-stacked / gamma, dim=-1))
        prev = row
    return prev[m]


def soft_dtw_divergence(x: torch.Tensor, y: torch.Tensor, gamma: float) -> torch.Tensor:
    """D_γ(x, y) per batch row (B,)."""
    return soft_dtw(x, y, gamma) - 0.5 * soft_dtw(x, x, gamma) - 0.5 * soft_dtw(y, y, gamma)
