"""Keyframe masks: the Gumbel soft top-k with straight-through of SFMS (Algorithm 1), and the
deterministic, static (uniform) and dense masks used at inference and in the Table III ablation.

All functions take logits ``s`` of shape (B, T) and return float masks of the same shape.
"""

from __future__ import annotations

import torch


def gumbel_noise(shape: tuple[int, ...], generator: torch.Generator | None = None,
                 device: torch.device | str = "cpu") -> torch.Tensor:
    """Gumbel(0, 1) samples −log(−log u), u ~ U(0, 1) clamped away from 0 and 1."""
    u = torch.rand(shape, generator=generator, device=device).clamp(1e-10, 1.0 - 1e-7)
    return -torch.log(-torch.log(u))


def relaxed_topk(logits: torch.Tensor, k: int, tau: float, eps: float = 1e-10) -> torch.Tensor:
    """The relaxed k-hot vector ``hotK`` of Algorithm 1 for already-perturbed logits a (B, T).

    Repeat k times: a ← a + log(max(1 − hot1, ε)); hot1 = softmax(a / τ); hotK ← hotK + hot1.
    Σ_t hotK = k exactly; single entries may exceed 1 at high τ.
    """
    a = logits
    hot1 = torch.zeros_like(logits)
    hot_k = torch.zeros_like(logits)
    for _ in range(k):
        a = a + torch.log(torch.clamp(1.0 - hot1, min=eps))
        hot1 = torch.softmax(a / tau, dim=-1)
        hot_k = hot_k + hot1
    return hot_k


def hard_topk(scores: torch.Tensor, k: int) -> torch.Tensor:
    """0/1 mask with ones at the k largest entries per row; ties go to the lower frame index."""
    order = torch.sort(scores, dim=-1, descending=True, stable=True).indices[..., :k]
    return torch.zeros_like(scores).scatter(-1, order, 1.0)


def gumbel_soft_topk(logits: torch.Tensor, k: int, tau: float, *, generator: torch.Generator | None = None,
                     noise: bool = True, eps: float = 1e-10) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Algorithm 1: returns (r, hard, hotK), each (B, T).

    ``hard`` has exactly k ones per row (top-k of hotK); ``r = hard + (hotK − sg(hotK))`` equals
    ``hard`` exactly in the forward pass and carries the gradient of hotK (straight-through).
    """
    if not 1 <= k <= logits.shape[-1]:
        raise ValueError(f"k must be in 1..{logits.shape[-1]}, got {k}")
    a = logits + gumbel_noise(tuple(logits.shape), generator, logits.device) if noise else logits
    hot_k = relaxed_topk(a, k, tau, eps)
    hard = hard_topk(hot_k.detach(), k)
    r = hard + (hot_k - hot_k.detach())
    return r, hard, hot_k


def static_mask(batch: int, window: int, k: int, device: torch.device | str = "cpu") -> torch.Tensor:
    """Uniform keyframes at i·⌊T/k⌋, i = 0..k−1 (Table III "static")."""
    mask = torch.zeros(batch, window, device=device)
    mask[:, torch.arange(k, device=device) * (window // k)] = 1.0
    return mask


def dense_mask(batch: int, window: int, device: torch.device | str = "cpu") -> torch.Tensor:
    """Every frame a keyframe (Table III "VQ-only" / dense per-frame quantisation)."""
    return torch.ones(batch, window, device=device)
