"""Fréchet distance between Gaussians fitted to motion features (the DualTalk/TIMAR/L2L helper).

Matches the reference metric scripts: statistics are the frame mean and ``np.cov(x, rowvar=False)``
(unbiased), the matrix square root is ``scipy.linalg.sqrtm`` of the product ``S1 @ S2``.
"""

from __future__ import annotations

import numpy as np
from scipy import linalg

from dyadbench.errors import InputError

SQRTM_RETRY_EPS = 1e-6
IMAG_TOLERANCE = 1e-3


def gaussian_stats(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Mean over frames and unbiased covariance of ``x`` (T, d).

    .. math:: \\mu = \\frac{1}{T}\\sum_t x_t, \\qquad
              \\Sigma = \\frac{1}{T-1}\\sum_t (x_t-\\mu)(x_t-\\mu)^\\top
    """
    x = np.asarray(x, dtype=np.float64)
    if x.ndim != 2 or x.shape[0] < 2:
        raise InputError(None, f"Fréchet statistics need (T>=2, d) features, got shape {x.shape}")
    return x.mean(axis=0), np.atleast_2d(np.cov(x, rowvar=False))


def frechet_distance(mu1: np.ndarray, sigma1: np.ndarray, mu2: np.ndarray, sigma2: np.ndarray) -> float:
    """Fréchet distance between N(mu1, sigma1) and N(mu2, sigma2).

    .. math:: d^2 = \\lVert\\mu_1-\\mu_2\\rVert^2 + \\operatorname{tr}\\Sigma_1 + \\operatorname{tr}\\Sigma_2
              - 2\\operatorname{tr}\\sqrt{\\Sigma_1\\Sigma_2}

    As in the reference: if ``sqrtm(S1 S2)`` has non-finite entries, 1e-6 is added to both diagonals
    and it is retried; a complex root is accepted only when the imaginary part of its diagonal is
    within 1e-3 of zero (the real part is then used), otherwise :class:`ValueError` is raised.
    Equal covariances give exactly ``|mu1 - mu2|^2`` up to round-off.
    """
    mu1, mu2 = np.atleast_1d(mu1), np.atleast_1d(mu2)
    sigma1, sigma2 = np.atleast_2d(sigma1), np.atleast_2d(sigma2)
    diff = mu1 - mu2
    covmean = linalg.sqrtm(sigma1.dot(sigma2))
    if not np.isfinite(covmean).all():
        offset = np.eye(sigma1.shape[0]) * SQRTM_RETRY_EPS
        covmean = linalg.sqrtm((sigma1 + offset).dot(sigma2 + offset))
    if np.iscomplexobj(covmean):
        if not np.allclose(np.diagonal(covmean).imag, 0, atol=IMAG_TOLERANCE):
            max_imag = np.max(np.abs(covmean.imag))
            raise ValueError(f"Fréchet distance: imaginary component {max_imag:.3g} in sqrtm(S1 S2)")
        covmean = covmean.real
    return float(diff.dot(diff) + np.trace(sigma1) + np.trace(sigma2) - 2.0 * np.trace(covmean))


def frechet_between(x: np.ndarray, y: np.ndarray) -> float:
    """Fréchet distance between Gaussians fitted to the frames of ``x`` and ``y`` (T, d)."""
    return frechet_distance(*gaussian_stats(x), *gaussian_stats(y))


def frechet_terms(x: np.ndarray, y: np.ndarray) -> tuple[float, float]:
    """The Fréchet distance of :func:`frechet_between` split into its mean and covariance terms.

    .. math:: \\mathrm{FD} = \\underbrace{\\lVert\\mu_x-\\mu_y\\rVert^2}_{\\text{mean term}}
              + \\underbrace{\\operatorname{tr}\\Sigma_x + \\operatorname{tr}\\Sigma_y
              - 2\\operatorname{tr}\\sqrt{\\Sigma_x\\Sigma_y}}_{\\text{covariance term}}

    Returns (mean term, covariance term); they sum to ``frechet_between(x, y)``. A copy of ``y`` moved by
    a constant offset has covariance term 0 (up to round-off), so its distance is the offset's squared norm.
    """
    mu_x, sigma_x = gaussian_stats(x)
    mu_y, sigma_y = gaussian_stats(y)
    mean_term = float((mu_x - mu_y).dot(mu_x - mu_y))
    return mean_term, frechet_distance(mu_x, sigma_x, mu_y, sigma_y) - mean_term
