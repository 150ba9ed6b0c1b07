"""The lightweight per-token diffusion head: an MLP of residual blocks with adaptive LayerNorm.

``y = cond_embed(z) + time_embed(t)`` modulates every block: ``h = LN(x)·(1 + scale) + shift``,
``x ← x + gate · MLP(h)``; a final modulated LayerNorm and a linear layer give 2·C channels
(x0 prediction and the variance interpolation). Modulations and the output layer start at zero.

The modulations depend on y only, not on x_t, so sampling computes them for all of its steps in one
pass (:meth:`DiffusionHead.modulation`) and then runs only the x_t path per step
(:meth:`DiffusionHead.denoise_modulated`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import torch
from torch import nn


def _modulate(x: torch.Tensor, shift: torch.Tensor, gain: torch.Tensor) -> torch.Tensor:
    """``x·(1 + scale) + shift`` with ``gain = 1 + scale`` precomputed."""
    return x * gain + shift


class TimestepEmbedder(nn.Module):
    """Sinusoidal embedding of the (original) diffusion timestep followed by a 2-layer SiLU MLP.

    The sinusoid table is computed in float32 whatever the model's dtype (as the release does) and then
    cast to the MLP's dtype."""

    def __init__(self, width: int, frequency_size: int = 256):
        super().__init__()
        self.frequency_size = frequency_size
        self.mlp = nn.Sequential(nn.Linear(frequency_size, width), nn.SiLU(), nn.Linear(width, width))

    def forward(self, t: torch.Tensor) -> torch.Tensor:
        half = self.frequency_size // 2
        freqs = torch.exp(-math.log(10_000) * torch.arange(half, dtype=torch.float32, device=t.device) / half)
        args = t.float()[:, None] * freqs[None]
        table = torch.cat([torch.cos(args), torch.sin(args)], dim=-1)
        return self.mlp(table.to(self.mlp[0].weight.dtype))


@dataclass(frozen=True)
class Modulation:
    """(shift, 1 + scale, gate) of every block and (shift, 1 + scale) of the final layer, computed from y."""

    blocks: tuple[tuple[torch.Tensor, ...], ...]
    final: tuple[torch.Tensor, ...]

    def at(self, index: int) -> "Modulation":
        """The modulation of entry ``index`` of the leading dimension (one sampling step)."""
        return Modulation(tuple(tuple(m[index] for m in block) for block in self.blocks),
                          tuple(m[index] for m in self.final))


class ResBlock(nn.Module):
    def __init__(self, width: int):
        super().__init__()
        self.norm = nn.LayerNorm(width, eps=1e-6)
        self.mlp = nn.Sequential(nn.Linear(width, width), nn.SiLU(), nn.Linear(width, width))
        self.modulation = nn.Sequential(nn.SiLU(), nn.Linear(width, 3 * width))

    def forward(self, x: torch.Tensor, shift: torch.Tensor, gain: torch.Tensor, gate: torch.Tensor) -> torch.Tensor:
        return x + gate * self.mlp(_modulate(self.norm(x), shift, gain))


class DiffusionHead(nn.Module):
    """Maps (x_t (B, C), timestep (B,), condition (B, cond_dim)) to (B, 2C)."""

    def __init__(self, channels: int, cond_dim: int, width: int, blocks: int):
        super().__init__()
        self.channels = channels
        self.time_embed = TimestepEmbedder(width)
        self.cond_embed = nn.Linear(cond_dim, width)
        self.input_proj = nn.Linear(channels, width)
        self.blocks = nn.ModuleList(ResBlock(width) for _ in range(blocks))
        self.final_norm = nn.LayerNorm(width, elementwise_affine=False, eps=1e-6)
        self.final_modulation = nn.Sequential(nn.SiLU(), nn.Linear(width, 2 * width))
        self.final = nn.Linear(width, 2 * channels)
        self._init_weights()

    def _init_weights(self) -> None:
        for module in self.modules():
            if isinstance(module, nn.Linear):
                nn.init.xavier_uniform_(module.weight)
                nn.init.zeros_(module.bias)
        nn.init.normal_(self.time_embed.mlp[0].weight, std=0.02)
        nn.init.normal_(self.time_embed.mlp[2].weight, std=0.02)
        for block in self.blocks:
            nn.init.zeros_(block.modulation[-1].weight)
            nn.init.zeros_(block.modulation[-1].bias)
        for layer in (self.final_modulation[-1], self.final):
            nn.init.zeros_(layer.weight)
            nn.init.zeros_(layer.bias)

    def forward(self, x: torch.Tensor, t: torch.Tensor, cond: torch.Tensor) -> torch.Tensor:
        return self.denoise(x, t, self.cond_embed(cond))

    def denoise(self, x: torch.Tensor, t: torch.Tensor, cond_embedding: torch.Tensor) -> torch.Tensor:
        """``forward`` with ``cond_embed(cond)`` computed by the caller."""
        return self.denoise_modulated(x, self.modulation(self.time_embed(t) + cond_embedding))

    def modulation(self, y: torch.Tensor) -> Modulation:
        """Every block's and the final layer's modulation from y (..., width); any leading dimensions."""
        def gained(shift: torch.Tensor, scale: torch.Tensor, *gate: torch.Tensor) -> tuple[torch.Tensor, ...]:
            return (shift, 1 + scale, *gate)

        return Modulation(tuple(gained(*block.modulation(y).chunk(3, dim=-1)) for block in self.blocks),
                          gained(*self.final_modulation(y).chunk(2, dim=-1)))

    def denoise_modulated(self, x: torch.Tensor, modulation: Modulation) -> torch.Tensor:
        """The x_t path: (B, C) to (B, 2C) under a modulation with leading shape (B,)."""
        h = self.input_proj(x)
        for block, (shift, gain, gate) in zip(self.blocks, modulation.blocks):
            h = block(h, shift, gain, gate)
        shift, gain = modulation.final
        return self.final(_modulate(self.final_norm(h), shift, gain))
