"""Vector quantisation (VQ-VAE) of keyframe latents: nearest codebook entry with straight-through.

Loss (SFMS eq. 13): w_cb·‖sg[z] − e‖² + w_commit·‖z − sg[e]‖², averaged over the positions given by
``weights`` (keyframes only).
"""

from __future__ import annotations

import torch
from torch import nn


class VQ(nn.Module):
    def __init__(self, n_codes: int, width: int, codebook_weight: float = 1.0, commit_weight: float = 1.0):
        super().__init__()
        self.n_codes = n_codes
        self.codebook = nn.Parameter(torch.randn(n_codes, width) / width ** 0.5)
        self.codebook_weight = codebook_weight
        self.commit_weight = commit_weight

    def nearest(self, z: torch.Tensor) -> torch.Tensor:
        flat = z.reshape(-1, z.shape[-1])
        dist = (flat.pow(2).sum(-1, keepdim=True) - 2 * flat @ self.codebook.t()
                + self.codebook.pow(2).sum(-1)[None, :])
        return dist.argmin(-1).reshape(z.shape[:-1])

    def forward(self, z: torch.Tensor, weights: torch.Tensor | None = None
                ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """(z_q with straight-through, indices, codebook + commitment loss over weighted positions)."""
        idx = self.nearest(z.detach())
        e = self.codebook[idx]
        per_pos_cb = (z.detach() - e).pow(2).mean(-1)
        per_pos_commit = (z - e.detach()).pow(2).mean(-1)
        w = torch.ones_like(per_pos_cb) if weights is None else weights
        denom = w.sum().clamp(min=1.0)
        loss = (self.codebook_weight * (per_pos_cb * w).sum() + self.commit_weight * (per_pos_commit * w).sum()) / denom
        return z + (e - z).detach(), idx, loss

    def embed_indices(self, indices: torch.Tensor) -> torch.Tensor:
        return self.codebook[indices]
