"""Finite scalar quantisation (Mentzer et al.): a fixed grid of Π L_j codes, no codebook loss.

Per channel j with L_j levels: bound z with tanh to half-width (L−1)(1+10⁻³)/2 (shifted by half a
step for even L so the grid is symmetric), round with straight-through, divide by ⌊L/2⌋ so codes
lie in [−1, 1]. Index = Σ_j digit_j · basis_j with digit_j = code_j·⌊L_j/2⌋ + ⌊L_j/2⌋ and
basis = cumprod([1, L_1, …, L_{n−1}]).
"""

from __future__ import annotations

import torch
from torch import nn


def round_ste(x: torch.Tensor) -> torch.Tensor:
    """Round in the forward pass, identity gradient."""
    return x + (torch.round(x) - x).detach()


class FSQ(nn.Module):
    """Linear(width → n) → FSQ grid → Linear(n → width)."""

    def __init__(self, levels: tuple[int, ...], width: int, eps: float = 1e-3):
        super().__init__()
        lv = torch.tensor(levels, dtype=torch.long)
        self.register_buffer("levels", lv, persistent=False)
        self.register_buffer("basis", torch.cumprod(torch.cat([torch.ones(1, dtype=torch.long), lv[:-1]]), 0),
                             persistent=False)
        self.eps = eps
        self.n_codes = int(torch.prod(lv))
        self.project_in = nn.Linear(width, len(levels))
        self.project_out = nn.Linear(len(levels), width)

    @property
    def half_width(self) -> torch.Tensor:
        return torch.div(self.levels, 2, rounding_mode="floor").float()

    def bound(self, z: torch.Tensor) -> torch.Tensor:
        half_l = (self.levels.float() - 1) * (1 + self.eps) / 2
        offset = torch.where(self.levels % 2 == 0, 0.5, 0.0)
        shift = torch.atanh(offset / half_l)
        return torch.tanh(z + shift) * half_l - offset

    def quantize(self, z: torch.Tensor) -> torch.Tensor:
        """Codes on the grid, in [−1, 1], for pre-projected z (..., n)."""
        return round_ste(self.bound(z)) / self.half_width

    def codes_to_indices(self, codes: torch.Tensor) -> torch.Tensor:
        digits = torch.round(codes * self.half_width + self.half_width).long()
        return (digits * self.basis).sum(-1)

    def indices_to_codes(self, indices: torch.Tensor) -> torch.Tensor:
        digits = torch.div(indices.long()[..., None], self.basis, rounding_mode="floor") % self.levels
        return (digits.float() - self.half_width) / self.half_width

    def forward(self, z: torch.Tensor, weights: torch.Tensor | None = None
                ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """(z_q (…, width), indices (…), quantisation loss = 0: FSQ has no codebook loss)."""
        codes = self.quantize(self.project_in(z))
        return self.project_out(codes), self.codes_to_indices(codes), z.new_zeros(())

    def embed_indices(self, indices: torch.Tensor) -> torch.Tensor:
        return self.project_out(self.indices_to_codes(indices))
