"""Diversity as the entropy of k-means cluster occupancy (SID in DualTalk/TIMAR, SI in L2L)."""

from __future__ import annotations

import numpy as np
from sklearn.cluster import KMeans

LOG_EPS = 1e-6


def occupancy_entropy(labels: np.ndarray, k: int) -> float:
    """Entropy in bits of a label histogram: :math:`-\\sum_i q_i \\log_2(q_i + 10^{-6})`.

    ``q_i`` = fraction of ``labels`` equal to ``i`` for i in 0..k-1 (empty clusters contribute 0).
    Bounded by ``log2 k`` (the 1e-6 only lowers it).
    """
    counts = np.bincount(np.asarray(labels, dtype=np.int64), minlength=k).astype(np.float64)
    q = counts / counts.sum()
    return float(-np.sum(q * np.log2(q + LOG_EPS)))


def fit_kmeans(fit_on: np.ndarray, k: int, random_state: int = 0) -> KMeans:
    """``KMeans(n_clusters=k, random_state=0, n_init="auto")`` fitted on ``fit_on`` (n, d) float64."""
    return KMeans(n_clusters=k, random_state=random_state, n_init="auto").fit(
        np.asarray(fit_on, dtype=np.float64))


def kmeans_entropy(fit_on: np.ndarray, label: np.ndarray, k: int, random_state: int = 0) -> float:
    """H(fit_on, label): fit k-means on ``fit_on``, label the rows of ``label``, occupancy entropy.

    .. math:: H = -\\sum_{i=1}^{k} q_i \\log_2(q_i + 10^{-6}), \\quad
              q_i = \\frac{|\\{t : c(\\text{label}_t) = i\\}|}{T}

    where ``c`` assigns a row to its nearest centroid of ``KMeans(k, random_state=0, n_init="auto")``
    fitted on ``fit_on``. In [0, log2 k].
    """
    model = fit_kmeans(fit_on, k, random_state)
    return occupancy_entropy(model.predict(np.asarray(label, dtype=np.float64)), k)
