"""Building blocks shared by the SFMS tokenizer and predictor: sinusoidal positions and pre-LN stacks."""

from __future__ import annotations

import math

import torch
from torch import nn


def sinusoidal(positions: torch.Tensor, dim: int) -> torch.Tensor:
    """Standard sin/cos encoding (…, dim) of integer or float positions (…)."""
    half = dim // 2
    freq = torch.exp(-math.log(10_000.0) * torch.arange(half, device=positions.device, dtype=torch.float32) / half)
    angle = positions.float()[..., None] * freq
    pe = torch.cat([torch.sin(angle), torch.cos(angle)], dim=-1)
    return nn.functional.pad(pe, (0, dim - 2 * half))


def positions(length: int, dim: int, start: int = 0, device: torch.device | str = "cpu") -> torch.Tensor:
    """(length, dim) sinusoidal encoding of positions start..start+length−1."""
    return sinusoidal(torch.arange(start, start + length, device=device), dim)


class EncoderStack(nn.Module):
    """``n`` pre-LN self-attention layers (GELU FFN); ``pad`` (B, L) True = key hidden."""

    def __init__(self, n: int, width: int, heads: int, ffn: int, dropout: float):
        super().__init__()
        self.layers = nn.ModuleList(
            nn.TransformerEncoderLayer(width, heads, ffn, dropout, activation="gelu", batch_first=True,
                                       norm_first=True) for _ in range(n))

    def forward(self, x: torch.Tensor, pad: torch.Tensor | None = None) -> torch.Tensor:
        for layer in self.layers:
            x = layer(x, src_key_padding_mask=pad)
        return x


class CrossStack(nn.Module):
    """``n`` pre-LN layers of {self-attention, cross-attention to ``memory``, FFN}."""

    def __init__(self, n: int, width: int, heads: int, ffn: int, dropout: float):
        super().__init__()
        self.layers = nn.ModuleList(
            nn.TransformerDecoderLayer(width, heads, ffn, dropout, activation="gelu", batch_first=True,
                                       norm_first=True) for _ in range(n))

    def forward(self, x: torch.Tensor, memory: torch.Tensor, memory_pad: torch.Tensor | None = None,
                pad: torch.Tensor | None = None) -> torch.Tensor:
        for layer in self.layers:
            x = layer(x, memory, tgt_key_padding_mask=pad, memory_key_padding_mask=memory_pad)
        return x


def with_sink(x: torch.Tensor, sink: torch.Tensor, hidden: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """Prepend a learned always-visible slot ``sink`` (width,) to x (B, L, W) and its key mask (B, L)."""
    b = x.shape[0]
    x = torch.cat([sink.expand(b, 1, -1), x], dim=1)
    pad = torch.cat([torch.zeros(b, 1, dtype=torch.bool, device=x.device), hidden], dim=1)
    return x, pad
