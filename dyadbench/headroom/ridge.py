"""Closed-form ridge regression from sufficient statistics, with the penalty chosen on a validation split.

A split is summarised by its moments over all rows z (with z₀ = 1) and targets y:
A = Σ z zᵀ, B = Σ z yᵀ, c = Σ y ∘ y (per output column) and the row count N, so neither the train nor the
validation rows are ever held in memory together.

Fit on the first m columns (features standardised with the train mean μ and standard deviation σ; the
intercept is not penalised; the history columns, from ``history_from`` on, penalised r times more):

.. math:: \\hat w(\\lambda, r) = \\arg\\min_w \\tfrac{1}{N}\\lVert Y - \\bar y - X_s w\\rVert^2
          + \\lambda\\, w^\\top R\\, w, \\qquad R = \\mathrm{diag}(1_{\\text{current}}, r\\,1_{\\text{history}})

With the history columns of X_s divided by √r (X_r), :math:`X_r^\\top X_r / N = V \\mathrm{diag}(e) V^\\top` and
:math:`\\hat v = V \\mathrm{diag}(1/(e_i+\\lambda)) V^\\top X_r^\\top (Y - \\bar y) / N` (then
:math:`\\hat w = R^{-1/2}\\hat v`): one eigendecomposition per r gives every λ of :data:`LAMBDAS`; r ranges
over :data:`HISTORY_RATIOS`, so history features that carry nothing can be shrunk away without shrinking the
current turn's (or the reverse). Each output column has its own solution, so (r, λ) is chosen per motion
component (exp, jaw, pose): the pair with the smallest validation squared error summed over that
component's columns, computed from the validation moments:

.. math:: \\mathrm{SSE}_j = c_j - 2\\,w_j^\\top B_{:,j} + w_j^\\top A\\,w_j

(w_j the raw-feature weights of column j, intercept included).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from dyadbench.errors import InputError
from dyadbench.motion import FLAME56, FLAME_COMPONENTS

#: Penalties tried (per standardised feature and row), decades from 1e-4 to 1e3.
LAMBDAS = tuple(float(x) for x in np.logspace(-4, 3, 8))
#: Penalty of the history columns relative to the current turn's (1 first: the only one without history).
HISTORY_RATIOS = (1.0, 0.01, 100.0, 10000.0)
#: A feature whose train standard deviation is below this is left unscaled (it is then constant).
MIN_STD = 1e-9


@dataclass
class Moments:
    """Running moments of rows (N, D) with a leading column of ones and targets (N, K)."""

    A: np.ndarray | None = None
    B: np.ndarray | None = None
    c: np.ndarray | None = None
    n: int = 0

    def add(self, rows: np.ndarray, target: np.ndarray) -> None:
        rows, target = np.asarray(rows, np.float64), np.asarray(target, np.float64)
        if self.A is None:
            self.A = np.zeros((rows.shape[1], rows.shape[1]))
            self.B = np.zeros((rows.shape[1], target.shape[1]))
            self.c = np.zeros(target.shape[1])
        self.A += rows.T @ rows
        self.B += rows.T @ target
        self.c += np.einsum("ij,ij->j", target, target)
        self.n += rows.shape[0]

    def head(self, m: int) -> "Moments":
        """The moments of the first ``m`` columns of the rows."""
        return Moments(self.A[:m, :m], self.B[:m], self.c, self.n)

    def sse(self, weights: np.ndarray) -> np.ndarray:
        """Squared error summed over the rows, per output column, of the predictions rows @ weights."""
        return self.c - 2.0 * np.sum(weights * self.B, axis=0) + np.sum(weights * (self.A @ weights), axis=0)


@dataclass(frozen=True)
class RidgeFit:
    """Weights on the raw rows (m, K), predictions = rows[:, :m] @ weights; λ and r chosen per component."""

    weights: np.ndarray
    penalty: dict[str, float] = field(default_factory=dict)
    history_ratio: dict[str, float] = field(default_factory=dict)
    val_mse: dict[str, float] = field(default_factory=dict)


def _scales(train: Moments, history_from: int, ratio: float) -> tuple[np.ndarray, np.ndarray]:
    """(μ, s) of the feature columns 1 … m−1: standardised column j is (z_j − μ_j)·s_j with s_j = 1/σ_j
    (0 for a constant column), divided by √ratio for the history columns."""
    mean = train.A[0, 1:] / train.n
    std = np.sqrt(np.clip(np.diag(train.A)[1:] / train.n - mean ** 2, 0.0, None))
    scale = np.where(std > MIN_STD, 1.0 / np.where(std > MIN_STD, std, 1.0), 0.0)
    scale[history_from - 1:] /= np.sqrt(ratio)
    return mean, scale


def ridge_path(train: Moments, history_from: int, ratio: float = 1.0) -> list[np.ndarray]:
    """Raw-row weights (m, K) of the ridge solution for every λ of :data:`LAMBDAS`, the columns from
    ``history_from`` on penalised ``ratio`` times more."""
    if train.A is None or train.n < 2:
        raise InputError(None, "ridge regression needs at least 2 training rows")
    mean, scale = _scales(train, history_from, ratio)
    mean_y = train.B[0] / train.n
    corr = (train.A[1:, 1:] / train.n - np.outer(mean, mean)) * np.outer(scale, scale)
    cov_xy = (train.B[1:] / train.n - np.outer(mean, mean_y)) * scale[:, None]
    eigval, eigvec = np.linalg.eigh((corr + corr.T) / 2)
    projected = eigvec.T @ cov_xy
    out = []
    for lam in LAMBDAS:
        w = scale[:, None] * (eigvec @ (projected / (np.clip(eigval, 0.0, None) + lam)[:, None]))
        out.append(np.vstack([(mean_y - mean @ w)[None, :], w]))
    return out


def fit(train: Moments, val: Moments, history_from: int) -> RidgeFit:
    """Ridge weights with (r, λ) chosen per FLAME component on ``val`` (see the module docstring); the columns
    from ``history_from`` on are the history (none when it equals the column count)."""
    ratios = HISTORY_RATIOS if history_from < train.A.shape[0] else HISTORY_RATIOS[:1]
    path = [(r, lam, w) for r in ratios for lam, w in zip(LAMBDAS, ridge_path(train, history_from, r))]
    errors = np.stack([val.sse(w) for _, _, w in path])  # (candidates, K)
    weights = np.empty_like(path[0][2])
    penalty, history_ratio, val_mse = {}, {}, {}
    for c in FLAME_COMPONENTS:
        cols = FLAME56.components[c]
        per_candidate = errors[:, cols].sum(axis=1)
        best = int(np.argmin(per_candidate))
        history_ratio[c], penalty[c], chosen = path[best]
        weights[:, cols] = chosen[:, cols]
        val_mse[c] = float(per_candidate[best] / (val.n * (cols.stop - cols.start)))
    return RidgeFit(weights=weights, penalty=penalty, history_ratio=history_ratio, val_mse=val_mse)
