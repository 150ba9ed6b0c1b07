"""The StyGazeTalk style encoder (spec §2.5) and its contrastive NT-Xent loss (spec §2.8).

SE(X) = mean_t TransformerEncoder(Linear(X) + PE)_t for a normalised motion window X ∈ R^{M×7}.
The Transformer width equals the style dimension d_s (D15), so mean pooling gives s ∈ R^{d_s}.
"""

from __future__ import annotations

import math

import torch
from torch import nn
from torch.nn import functional as F

from models.stygazetalk.config import MOTION_DIM, StyleEncoderConfig


class SinusoidalPositions(nn.Module):
    """Adds the standard sinusoidal encoding of each frame's position (D14; a different vector per frame).

    PE[t, 2k] = sin(t / 10000^{2k/d}), PE[t, 2k+1] = cos(t / 10000^{2k/d}).
    """

    def __init__(self, dim: int, max_len: int = 4096):
        super().__init__()
        position = torch.arange(max_len, dtype=torch.float32)[:, None]
        div = torch.exp(torch.arange(0, dim, 2, dtype=torch.float32) * (-math.log(10000.0) / dim))
        table = torch.zeros(max_len, dim)
        table[:, 0::2] = torch.sin(position * div)
        table[:, 1::2] = torch.cos(position * div)
        self.register_buffer("table", table, persistent=False)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return x + self.table[: x.shape[1]][None]


class StyleEncoder(nn.Module):
    """Motion window (B, M, 7), normalised → style vector (B, d_s)."""

    def __init__(self, cfg: StyleEncoderConfig):
        super().__init__()
        self.cfg = cfg.validate()
        velocity = cfg.input_features == "centred+velocity"
        self.proj = nn.Linear(2 * MOTION_DIM if velocity else MOTION_DIM, cfg.d_s)
        if velocity:  # train-split rms of the normalised frame differences, set by the trainer (D47)
            self.register_buffer("velocity_scale", torch.ones(MOTION_DIM))
        self.positions = SinusoidalPositions(cfg.d_s)
        self.dropout = nn.Dropout(cfg.dropout)
        layer = nn.TransformerEncoderLayer(cfg.d_s, cfg.heads, cfg.ffn_mult * cfg.d_s, cfg.dropout,
                                           activation="gelu", batch_first=True)
        self.encoder = nn.TransformerEncoder(layer, cfg.layers, enable_nested_tensor=False)

    def features(self, window: torch.Tensor) -> torch.Tensor:
        """What the projection reads (D47): the angles, or the angles centred per window, with their
        frame-to-frame differences divided by their train-split rms (so every input channel is O(1))."""
        if self.cfg.input_features == "angles":
            return window
        centred = window - window.mean(dim=1, keepdim=True)
        if self.cfg.input_features == "centred":
            return centred
        velocity = torch.diff(window, dim=1, prepend=window[:, :1]) / self.velocity_scale
        return torch.cat([centred, velocity], dim=-1)

    def forward(self, window: torch.Tensor) -> torch.Tensor:
        h = self.dropout(self.positions(self.proj(self.features(window))))
        return self.encoder(h).mean(dim=1)


def nt_xent(a: torch.Tensor, b: torch.Tensor, temperature: float, reduction: str = "mean",
            labels: torch.Tensor | None = None) -> torch.Tensor:
    """NT-Xent over B positive pairs (a_i, b_i): the 2B views, each with its partner as the positive.

    .. math:: \\ell_i = -\\log \\frac{\\exp(\\cos(z_i, z_{p(i)})/\\tau)}{\\sum_{k \\ne i} \\exp(\\cos(z_i, z_k)/\\tau)},
       \\quad z = [a; b], \\; p(i) = i \\pm B

    ``reduction="mean"`` averages ℓ over the 2B views (D22); ``"sum"`` is the paper's printed sum.
    ``labels`` (B,) (e.g. speaker ids of the pairs, D46) drop from view i's denominator every other
    view with i's label, except its partner: same-label windows are then neither positives nor negatives.
    """
    if a.shape != b.shape or a.ndim != 2:
        raise ValueError(f"nt_xent needs two (B, d) tensors of one shape, got {tuple(a.shape)} and {tuple(b.shape)}")
    n = a.shape[0]
    z = F.normalize(torch.cat([a, b], dim=0), dim=1)
    logits = z @ z.T / temperature
    target = torch.cat([torch.arange(n, 2 * n), torch.arange(0, n)]).to(z.device)
    drop = torch.eye(2 * n, dtype=torch.bool, device=z.device)
    if labels is not None:
        if labels.shape != (n,):
            raise ValueError(f"nt_xent labels must have shape ({n},), got {tuple(labels.shape)}")
        views = torch.cat([labels, labels]).to(z.device)
        drop = drop | (views[:, None] == views[None, :])
        drop[torch.arange(2 * n, device=z.device), target] = False  # the partner stays the positive
    logits = logits.masked_fill(drop, float("-inf"))
    return F.cross_entropy(logits, target, reduction=reduction)
