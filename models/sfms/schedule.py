"""Learning-rate and temperature schedules of SFMS training (spec §2.4, §2.10, §3.4)."""

from __future__ import annotations

import math


def cosine(step: int, total: int, lr: float, lr_min: float) -> float:
    """Cosine annealing from ``lr`` at step 0 to ``lr_min`` at step ``total``."""
    if total <= 0:
        return lr
    frac = min(max(step / total, 0.0), 1.0)
    return lr_min + 0.5 * (lr - lr_min) * (1.0 + math.cos(math.pi * frac))


def warmup_cosine(step: int, total: int, warmup: int, lr: float, lr_min: float) -> float:
    """Linear warm-up over ``warmup`` steps, then cosine over the rest."""
    if step < warmup:
        return lr * (step + 1) / warmup
    return cosine(step - warmup, total - warmup, lr, lr_min)


def temperature(step: int, total: int, tau_start: float, tau_min: float, anneal_frac: float) -> float:
    """τ = max(τ_min, τ₀·exp(−λ·step)), λ chosen so τ_min is reached at ``anneal_frac`` of ``total``."""
    if tau_min >= tau_start or total <= 0 or anneal_frac <= 0:
        return tau_start
    lam = math.log(tau_start / tau_min) / (anneal_frac * total)
    return max(tau_min, tau_start * math.exp(-lam * step))
