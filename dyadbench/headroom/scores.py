"""The benchmark's FD, P-FD and MSE per component, for predictions of whole turns.

Each prediction is one direction's turns concatenated in order, as the streaming protocol assembles them
(whole turns only, ``tail = truncate``), scored against the agent's and the partner's motion of the same
frames with the DualTalk/TIMAR suite's own functions (:func:`dyadbench.metrics.dualtalk.fd`,
:func:`~dyadbench.metrics.dualtalk.pfd`, :func:`~dyadbench.metrics.dualtalk.mse`) per FLAME component, then
averaged over predictions (the scorer's plain mean over clips) and multiplied by the suite's publication
scale (:data:`dyadbench.metrics.dualtalk.SCALE`), as the leaderboards print them. The suite's other
metrics (SID, rPCC, ...) are not computed here.
"""

from __future__ import annotations

import numpy as np

from dyadbench.metrics import dualtalk as suite
from dyadbench.motion import FLAME56, FLAME_COMPONENTS

METRICS = ("mse", "pfd", "fd")
KEYS = tuple(f"{m}_{c}" for m in METRICS for c in FLAME_COMPONENTS)


def prediction_scores(pred: np.ndarray, gt: np.ndarray, partner: np.ndarray) -> dict[str, float]:
    """Raw MSE, P-FD and FD per component of one prediction (T, 56) against its ground truth and partner."""
    out = {}
    for c in FLAME_COMPONENTS:
        p, g, a = (FLAME56.component(np.asarray(x, np.float64), c) for x in (pred, gt, partner))
        out[f"mse_{c}"] = suite.mse(p, g)
        out[f"pfd_{c}"] = suite.pfd(p, g, a)
        out[f"fd_{c}"] = suite.fd(p, g)
    return out


def scaled_means(rows: list[dict[str, float]]) -> dict[str, float]:
    """Mean over predictions of every key, times the suite's publication scale."""
    return {k: float(np.mean([r[k] for r in rows])) * suite.SCALE[k] for k in KEYS}
