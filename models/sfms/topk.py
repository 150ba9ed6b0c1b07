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


def neighbourhood(x: torch.Tensor, radius: int) -> torch.Tensor:
    """Box sum of ``x`` (B, T) over frames t − radius .. t + radius (zero-padded); radius 0 is ``x``."""
    if radius == 0:
        return x
    kernel = x.new_ones(1, 1, 2 * radius + 1)
    return torch.nn.functional.conv1d(x[:, None], kernel, padding=radius)[:, 0]


def relaxed_topk(logits: torch.Tensor, k: int, tau: float, eps: float = 1e-10, radius: int = 0) -> torch.Tensor:
    """The relaxed k-hot vector ``hotK`` of Algorithm 1 for already-perturbed logits a (B, T).

    Repeat k times: a ← a + log(max(1 − N_r(hot1), ε)); hot1 = softmax(a / τ); hotK ← hotK + hot1,
    where N_r is the box sum over ±``radius`` frames. Radius 0 is Algorithm 1 as published (only the
    softly chosen frame is suppressed); radius r also suppresses its r neighbours on each side.
    Σ_t hotK = k exactly; single entries may exceed 1 at high τ.
    """
    a = logits
    hot1 = torch.zeros_like(logits)
    hot_k = torch.zeros_like(logits)
    for _ in range(k):
        a = a + torch.log(torch.clamp(1.0 - neighbourhood(hot1, radius), min=eps))
        hot1 = torch.softmax(a / tau, dim=-1)
        hot_k = hot_k + hot1
    return hot_k


def hard_topk(scores: torch.Tensor, k: int, radius: int = 0) -> torch.Tensor:
    """0/1 mask with exactly k ones per row, by greedy non-maximum suppression: each round picks the
    largest score among frames not within ±``radius`` of an earlier pick (once none is left, the
    largest unpicked frame). Radius 0 is plain top-k. Ties go to the lower frame index. This is the
    τ → 0 limit of :func:`relaxed_topk` with the same radius.
    """
    frames = torch.arange(scores.shape[-1], device=scores.device)
    key = scores.detach().double()
    span = (key.amax(-1, keepdim=True) - key.amin(-1, keepdim=True)) + 1.0  # > any score difference
    picked = torch.zeros_like(key, dtype=torch.bool)
    excluded = torch.zeros_like(picked)
    for _ in range(k):
        j = (key - span * excluded.double()).masked_fill(picked, float("-inf")).argmax(-1, keepdim=True)
        picked.scatter_(-1, j, True)
        excluded |= (frames - j).abs() <= radius
    return picked.to(scores.dtype)


def gumbel_soft_topk(logits: torch.Tensor, k: int, tau: float, *, generator: torch.Generator | None = None,
                     noise: bool = True, eps: float = 1e-10,
                     radius: int = 0) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Algorithm 1: returns (r, hard, hotK), each (B, T).

    ``hard`` has exactly k ones per row (:func:`hard_topk` of hotK with the same ``radius``);
    ``r = hard + (hotK − sg(hotK))`` equals ``hard`` exactly in the forward pass and carries the
    gradient of hotK (straight-through).
    """
    if not 1 <= k <= logits.shape[-1]:
        raise ValueError(f"k must be in 1..{logits.shape[-1]}, got {k}")
    a = logits + gumbel_noise(tuple(logits.shape), generator, logits.device) if noise else logits
    hot_k = relaxed_topk(a, k, tau, eps, radius)
    hard = hard_topk(hot_k.detach(), k, radius)
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
