"""Pre-LN transformer blocks whose attention can continue from cached keys/values of earlier turns.

A block maps the current tokens ``x`` (B, Lq, D), an optional additive attention bias broadcastable
to (B, H, Lq, Lk) (``-inf`` = not allowed) and optional ``past`` = (k, v) of earlier tokens
(B, H, Lp, D/H) to the block output and the (k, v) of the current tokens only, which a caller may
keep and pass back later. Full-sequence encoding is the same call with ``past = None``.
"""

from __future__ import annotations

import torch
import torch.nn.functional as F
from torch import nn

KV = tuple[torch.Tensor, torch.Tensor]


class Attention(nn.Module):
    def __init__(self, dim: int, heads: int, dropout: float, attn_dropout: float):
        super().__init__()
        self.heads = heads
        self.attn_dropout = attn_dropout
        self.qkv = nn.Linear(dim, 3 * dim, bias=True)
        self.proj = nn.Linear(dim, dim)
        self.proj_drop = nn.Dropout(dropout)

    def heads_qkv(self, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """q, k, v of the tokens ``x`` (B, L, D), each (B, H, L, D/H)."""
        b, length, dim = x.shape
        q, k, v = self.qkv(x).view(b, length, 3, self.heads, dim // self.heads).permute(2, 0, 3, 1, 4)
        return q, k, v

    def attend(self, q: torch.Tensor, keys: torch.Tensor, values: torch.Tensor,
               bias: torch.Tensor | None = None) -> torch.Tensor:
        """Scaled dot-product attention per head, (B, H, Lq, D/H)."""
        return F.scaled_dot_product_attention(q, keys, values, attn_mask=bias,
                                              dropout_p=self.attn_dropout if self.training else 0.0)

    def merge(self, heads: torch.Tensor) -> torch.Tensor:
        """(B, H, L, D/H) -> output projection (B, L, D)."""
        b, h, length, dh = heads.shape
        return self.proj_drop(self.proj(heads.transpose(1, 2).reshape(b, length, h * dh)))

    def forward(self, x: torch.Tensor, bias: torch.Tensor | None, past: KV | None) -> tuple[torch.Tensor, KV]:
        q, k, v = self.heads_qkv(x)
        keys, values = (k, v) if past is None else (torch.cat([past[0], k], 2), torch.cat([past[1], v], 2))
        return self.merge(self.attend(q, keys, values, bias)), (k, v)


class Block(nn.Module):
    """``x + Attn(LN(x))`` then ``x + MLP(LN(x))`` (GELU MLP of width ``mlp_ratio·D``, dropouts)."""

    def __init__(self, dim: int, heads: int, mlp_ratio: float, dropout: float, attn_dropout: float):
        super().__init__()
        hidden = int(dim * mlp_ratio)
        self.norm1 = nn.LayerNorm(dim, eps=1e-6)
        self.attn = Attention(dim, heads, dropout, attn_dropout)
        self.norm2 = nn.LayerNorm(dim, eps=1e-6)
        self.mlp = nn.Sequential(nn.Linear(dim, hidden), nn.GELU(), nn.Dropout(dropout),
                                 nn.Linear(hidden, dim), nn.Dropout(dropout))

    def forward(self, x: torch.Tensor, bias: torch.Tensor | None = None,
                past: KV | None = None) -> tuple[torch.Tensor, KV]:
        attended, kv = self.attn(self.norm1(x), bias, past)
        return self.feed_forward(x + attended), kv

    def feed_forward(self, x: torch.Tensor) -> torch.Tensor:
        return x + self.mlp(self.norm2(x))


def concat_past(turns: list[KV]) -> KV | None:
    """Keys/values of several earlier turns (oldest first) joined along the token axis."""
    if not turns:
        return None
    return torch.cat([k for k, _ in turns], 2), torch.cat([v for _, v in turns], 2)
