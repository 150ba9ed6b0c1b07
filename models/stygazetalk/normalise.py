"""Per-dimension z-scoring with train-split statistics (D4), kept as buffers so checkpoints carry them."""

from __future__ import annotations

import numpy as np
import torch
from torch import nn

STD_FLOOR = 1e-6


class ZScore(nn.Module):
    """x ↦ (x − μ) / σ per last-axis dimension; σ is floored at 1e-6 so constant dims stay finite."""

    def __init__(self, dim: int):
        super().__init__()
        self.register_buffer("mean", torch.zeros(dim))
        self.register_buffer("std", torch.ones(dim))

    @classmethod
    def fit(cls, rows: np.ndarray) -> "ZScore":
        """Statistics of ``rows`` (n, dim), e.g. every train frame stacked."""
        rows = np.asarray(rows, dtype=np.float64)
        z = cls(rows.shape[1])
        z.mean.copy_(torch.from_numpy(rows.mean(axis=0)).float())
        z.std.copy_(torch.from_numpy(np.maximum(rows.std(axis=0), STD_FLOOR)).float())
        return z

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return (x - self.mean) / self.std

    def inverse(self, x: torch.Tensor) -> torch.Tensor:
        return x * self.std + self.mean

    def np(self, x: np.ndarray) -> np.ndarray:
        """Normalise a numpy array (float32)."""
        return ((np.asarray(x, dtype=np.float32) - self.mean.numpy()) / self.std.numpy()).astype(np.float32)

    def np_inverse(self, x: np.ndarray) -> np.ndarray:
        return (np.asarray(x, dtype=np.float32) * self.std.numpy() + self.mean.numpy()).astype(np.float32)
