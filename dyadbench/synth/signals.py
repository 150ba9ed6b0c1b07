"""Small, vectorised signal helpers of the synthetic-corpus generator (frame- or sample-rate arrays)."""

from __future__ import annotations

import numpy as np
from scipy.signal import lfilter


def ou_process(rng: np.random.Generator, n: int, tau: float, std: np.ndarray | float, dims: int = 1) -> np.ndarray:
    """Stationary Ornstein–Uhlenbeck (AR(1)) noise: (n, dims), time constant ``tau`` in samples.

    x_t = rho x_{t-1} + sqrt(1 - rho^2) e_t with rho = exp(-1/tau), x_0 ~ N(0, 1), scaled by ``std``.
    """
    rho = float(np.exp(-1.0 / max(tau, 1e-6)))
    eps = rng.standard_normal((n, dims))
    x = lfilter([np.sqrt(1.0 - rho * rho)], [1.0, -rho], eps, axis=0, zi=(rho * eps[:1]))[0]
    return x * np.asarray(std)


def lowpass(x: np.ndarray, tau: float) -> np.ndarray:
    """One-pole causal low-pass along axis 0 with time constant ``tau`` samples (unit DC gain)."""
    if tau <= 0:
        return x
    rho = float(np.exp(-1.0 / tau))
    return lfilter([1.0 - rho], [1.0, -rho], x, axis=0)


def delay(x: np.ndarray, lag: int) -> np.ndarray:
    """x delayed by ``lag`` >= 0 samples along axis 0; the first ``lag`` samples are 0 (causal)."""
    if lag <= 0:
        return x
    out = np.zeros_like(x)
    out[lag:] = x[: len(x) - lag]
    return out


def impulses(n: int, at: np.ndarray, weights: np.ndarray | None = None) -> np.ndarray:
    """(n,) train of impulses at integer positions ``at`` (those outside [0, n) are dropped)."""
    at = np.asarray(at, dtype=np.int64)
    w = np.ones(len(at)) if weights is None else np.asarray(weights, dtype=np.float64)
    keep = (at >= 0) & (at < n)
    out = np.zeros(n)
    np.add.at(out, at[keep], w[keep])
    return out


def causal_response(n: int, at: np.ndarray, kernel: np.ndarray, weights: np.ndarray | None = None) -> np.ndarray:
    """Sum of ``kernel`` copies starting at each position in ``at`` (scaled by ``weights``): (n,)."""
    return np.convolve(impulses(n, at, weights), kernel)[:n]


def upsample_linear(values: np.ndarray, factor: int, dtype: type = np.float64) -> np.ndarray:
    """Linear interpolation of a regularly sampled 1-d signal by an integer ``factor``: (len * factor,).

    Sample j of block k is ``v[k] + (v[k+1] - v[k]) * j / factor`` (the last block holds its value).
    """
    v = np.asarray(values, dtype=dtype)
    nxt = np.append(v[1:], v[-1:]) if len(v) else v
    frac = (np.arange(factor) / factor).astype(dtype)
    return (v[:, None] + (nxt - v)[:, None] * frac[None, :]).reshape(-1)


def block_mean(x: np.ndarray, factor: int) -> np.ndarray:
    """Mean over consecutive blocks of ``factor`` samples (the ragged tail is dropped)."""
    n = len(x) // factor
    return x[: n * factor].reshape(n, factor, *x.shape[1:]).mean(axis=1)


def nod_kernel(fps: float, freq_hz: float = 2.5, decay_s: float = 0.25, length_s: float = 0.8) -> np.ndarray:
    """A head nod on the pitch axis: a damped sine starting downwards, unit peak (frames)."""
    t = np.arange(int(round(length_s * fps))) / fps
    k = np.sin(2 * np.pi * freq_hz * t) * np.exp(-t / decay_s)
    return k / np.abs(k).max()


def bump_kernel(fps: float, rise_s: float, decay_s: float, length_s: float) -> np.ndarray:
    """A smooth rise-then-decay bump (e.g. a smile), unit peak (frames)."""
    t = np.arange(int(round(length_s * fps))) / fps
    k = (1.0 - np.exp(-t / rise_s)) * np.exp(-t / decay_s)
    return k / k.max()
