"""Gaussian diffusion for the per-token head: cosine schedule, x0 prediction, learned variance range.

The arithmetic follows the improved-DDPM code used by masked autoregression with a diffusion loss
(and by TIMAR's release):

- cosine schedule: ``alpha_bar(s) = cos²((s + 0.008) / 1.008 · π/2)``,
  ``beta_i = min(1 − alpha_bar((i+1)/T) / alpha_bar(i/T), 0.999)``, T = 1000 training steps;
- the network predicts x0 (first C channels) and a variance interpolation v ∈ [−1, 1] (last C):
  ``log σ² = (v+1)/2 · log β_t + (1 − (v+1)/2) · log β̃_t`` (β̃ = posterior variance, clipped at t=0);
- training loss = the caller's x0 regression term + the variational-bound term (KL of the true and
  predicted posteriors in bits; discretised Gaussian decoder NLL at t = 0), with the mean frozen so
  the bound trains only the variance;
- sampling uses a respaced process: ``space_timesteps(1000, "5")`` keeps original steps
  0, 250, 500, 749, 999, which are fed to the network; ancestral DDPM steps, temperature scaling the
  noise, no clipping of x0; v clamped to [-1, 1] by default (see :meth:`GaussianDiffusion.sample`).
"""

from __future__ import annotations

import math
from typing import Callable, Sequence

import numpy as np
import torch


def cosine_betas(num_steps: int, max_beta: float = 0.999) -> np.ndarray:
    def alpha_bar(s: float) -> float:
        return math.cos((s + 0.008) / 1.008 * math.pi / 2) ** 2

    return np.array([min(1 - alpha_bar((i + 1) / num_steps) / alpha_bar(i / num_steps), max_beta)
                     for i in range(num_steps)], dtype=np.float64)


def space_timesteps(num_steps: int, count: int) -> list[int]:
    """Evenly strided original timesteps (improved-DDPM ``space_timesteps(T, str(count))``)."""
    if count == 1:
        return [0]
    stride = (num_steps - 1) / (count - 1)
    return sorted({round(i * stride) for i in range(count)})


def _normal_kl(mean1: torch.Tensor, logvar1: torch.Tensor, mean2: torch.Tensor, logvar2: torch.Tensor) -> torch.Tensor:
    return 0.5 * (-1.0 + logvar2 - logvar1 + torch.exp(logvar1 - logvar2) + (mean1 - mean2) ** 2 * torch.exp(-logvar2))


def _approx_std_normal_cdf(x: torch.Tensor) -> torch.Tensor:
    return 0.5 * (1.0 + torch.tanh(math.sqrt(2.0 / math.pi) * (x + 0.044715 * x ** 3)))


def _discretized_gaussian_log_likelihood(x: torch.Tensor, means: torch.Tensor, log_scales: torch.Tensor) -> torch.Tensor:
    """Log-likelihood of x under a Gaussian discretised to 255 bins on [−1, 1] (improved DDPM)."""
    centered = x - means
    inv_stdv = torch.exp(-log_scales)
    cdf_plus = _approx_std_normal_cdf(inv_stdv * (centered + 1.0 / 255.0))
    cdf_min = _approx_std_normal_cdf(inv_stdv * (centered - 1.0 / 255.0))
    log_cdf_plus = torch.log(cdf_plus.clamp(min=1e-12))
    log_one_minus_cdf_min = torch.log((1.0 - cdf_min).clamp(min=1e-12))
    cdf_delta = cdf_plus - cdf_min
    return torch.where(x < -0.999, log_cdf_plus,
                       torch.where(x > 0.999, log_one_minus_cdf_min, torch.log(cdf_delta.clamp(min=1e-12))))


def _normal(shape: tuple[int, ...], generator: torch.Generator | Sequence[torch.Generator]) -> torch.Tensor:
    """Standard normal noise of ``shape`` from one generator, or row i of it from ``generator[i]``."""
    if isinstance(generator, torch.Generator):
        return torch.randn(shape, generator=generator)
    return torch.stack([torch.randn(shape[1:], generator=g) for g in generator])


class GaussianDiffusion:
    """A (possibly respaced) diffusion process; ``timestep_map[i]`` is the network's timestep for step i."""

    def __init__(self, betas: np.ndarray, timestep_map: list[int]):
        self.betas = np.asarray(betas, dtype=np.float64)
        self.num_steps = len(self.betas)
        self.timestep_map = torch.tensor(timestep_map, dtype=torch.long)
        alphas = 1.0 - self.betas
        acp = np.cumprod(alphas)
        acp_prev = np.append(1.0, acp[:-1])
        posterior_variance = self.betas * (1.0 - acp_prev) / (1.0 - acp)
        tables = {
            "sqrt_acp": np.sqrt(acp),
            "sqrt_one_minus_acp": np.sqrt(1.0 - acp),
            "log_betas": np.log(self.betas),
            "posterior_log_var": np.log(np.append(posterior_variance[1], posterior_variance[1:])),
            "posterior_coef1": self.betas * np.sqrt(acp_prev) / (1.0 - acp),
            "posterior_coef2": (1.0 - acp_prev) * np.sqrt(alphas) / (1.0 - acp),
        }
        self._tables = {k: torch.tensor(v, dtype=torch.float32) for k, v in tables.items()}
        self.alphas_cumprod = acp

    @classmethod
    def training(cls, num_steps: int) -> "GaussianDiffusion":
        return cls(cosine_betas(num_steps), list(range(num_steps)))

    @classmethod
    def respaced(cls, num_steps: int, count: int) -> "GaussianDiffusion":
        """The process restricted to ``space_timesteps(num_steps, count)`` (betas recomputed from ᾱ)."""
        keep = space_timesteps(num_steps, count)
        acp = np.cumprod(1.0 - cosine_betas(num_steps))
        betas, last = [], 1.0
        for t in keep:
            betas.append(1.0 - acp[t] / last)
            last = acp[t]
        return cls(np.array(betas), keep)

    def _take(self, name: str, t: torch.Tensor | int) -> torch.Tensor:
        """Table entries at steps ``t``: (B, 1) for a tensor of steps, a 0-d tensor for one step index."""
        if isinstance(t, int):
            return self._tables[name][t]
        return self._tables[name].to(t.device)[t].unsqueeze(-1)

    def q_sample(self, x0: torch.Tensor, t: torch.Tensor, noise: torch.Tensor) -> torch.Tensor:
        return self._take("sqrt_acp", t) * x0 + self._take("sqrt_one_minus_acp", t) * noise

    def _posterior_mean(self, x0: torch.Tensor, xt: torch.Tensor, t: torch.Tensor) -> torch.Tensor:
        return self._take("posterior_coef1", t) * x0 + self._take("posterior_coef2", t) * xt

    def p_mean_logvar(self, output: torch.Tensor, xt: torch.Tensor, t: torch.Tensor | int,
                      clamp_variance: bool = False) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """(posterior mean, log variance, x0 prediction) from the network's 2C-channel output.

        ``clamp_variance`` keeps v in [-1, 1], i.e. the variance between β̃_t and β_t (used in sampling).
        """
        channels = xt.shape[-1]
        x0, v = output[..., :channels], output[..., channels:]
        if clamp_variance:
            v = v.clamp(-1.0, 1.0)
        frac = (v + 1.0) / 2.0
        log_var = frac * self._take("log_betas", t) + (1.0 - frac) * self._take("posterior_log_var", t)
        return self._posterior_mean(x0, xt, t), log_var, x0

    def vb_term(self, output: torch.Tensor, x0: torch.Tensor, xt: torch.Tensor, t: torch.Tensor) -> torch.Tensor:
        """Variational-bound term per token in bits, training only the variance (x0 output detached)."""
        channels = xt.shape[-1]
        frozen = torch.cat([output[..., :channels].detach(), output[..., channels:]], dim=-1)
        mean, log_var, _ = self.p_mean_logvar(frozen, xt, t)
        true_mean = self._posterior_mean(x0, xt, t)
        true_log_var = self._take("posterior_log_var", t)
        kl = _normal_kl(true_mean, true_log_var, mean, log_var).mean(-1) / math.log(2.0)
        nll = -_discretized_gaussian_log_likelihood(x0, mean, 0.5 * log_var).mean(-1) / math.log(2.0)
        return torch.where(t == 0, nll, kl)

    @torch.no_grad()
    def sample(self, denoise: Callable[[torch.Tensor, int], torch.Tensor], shape: tuple[int, ...],
               generator: torch.Generator | Sequence[torch.Generator], temperature: float = 1.0,
               device: torch.device | str = "cpu", clamp_variance: bool = True) -> torch.Tensor:
        """Ancestral sampling from pure noise; ``denoise(x_t, i)`` returns 2C channels for step i, whose
        network timestep is ``timestep_map[i]`` (every row of x_t is at the same step).

        All noise comes from ``generator`` in a fixed order (x_T first, then one draw per step with
        t > 0), so equal seeds give equal samples whatever the caller's cache state. With a list of
        generators the first dimension of ``shape`` is one per generator, each row drawn from its own in
        that order, as if sampled alone.

        ``clamp_variance`` (default True) keeps v in [-1, 1]. The released code does not clamp; with a
        well-trained head v stays in that range and clamping changes nothing, but an under-trained head
        can predict v far outside it, and in the respaced process (where β and β̃ differ by orders of
        magnitude) the extrapolated variance explodes (σ of 10^6 seen at the 250 → 0 step).
        """
        x = _normal(shape, generator).to(device)
        for i in reversed(range(self.num_steps)):
            mean, log_var, _ = self.p_mean_logvar(denoise(x, i), x, i, clamp_variance=clamp_variance)
            if i > 0:
                noise = _normal(shape, generator).to(device)
                x = mean + torch.exp(0.5 * log_var) * noise * temperature
            else:
                x = mean
        return x
