"""The Seamless Interaction suite: DualTalk-line metrics per motion component, REACT-line metrics on emotion.

Per predicted agent (pure arrays in, numbers out; ``p`` prediction, ``g`` the agent's ground truth, ``a``
the partner's, all in the ``seamless`` / ``seamless-gaze`` layout of :mod:`dyadbench.datasets.seamless`):

1. **Scored frames.** Frames where the agent's *and* the partner's movement features are valid (the last
   column of ``g`` and ``a`` is 1), after truncation to the shortest length, kept in order. Every metric
   below sees those frames only; invalid (zero-filled) frames never enter any metric, and their count is
   reported (``frames_excluded``). The prediction's own last column is ignored.
2. **DualTalk line** per component ``expression`` (128), ``head`` (3) and, in ``seamless-gaze``, ``gaze`` (2):
   FD, P-FD, MSE, SID, rPCC, Var (prediction and ground truth) and Div (prediction and ground truth), the
   functions of :mod:`dyadbench.metrics.dualtalk` (formulas there), with SID's k = 40 (expression) or 10.
3. **REACT line** on the 34-d emotion stream (24 AU intensities, valence, arousal, 8 emotion scores), one
   deterministic reaction per agent (R = 1) and the agent's own ground truth as its only appropriate real
   reaction: FRCorr = mean CCC over the 34 channels (:func:`dyadbench.metrics.react.fr_corr_per_reaction`);
   FRDist = grouped DTW (AU 1/24, valence-arousal 1, emotion scores 1/8: REACT's per-group weights
   1/15, 1, 1/8 with 24 AUs in place of 15); FRVar (ddof = 1, :func:`dyadbench.metrics.react.time_variances`);
   FRSyn = TLCC offset of the prediction against the partner's emotion, lags of ±49 frames as REACT
   (1.63 s at 30 Hz; :mod:`dyadbench.metrics.tlcc`). FRDiv and FRDvs are not computed: they need R ≥ 2
   reactions per speaker. Difference from REACT's 25-d features: 24 continuous AU intensities (REACT: 15
   binary AUs) and 8 emotion scores in the order anger, contempt, disgust, fear, happiness, neutral,
   sadness, surprise (REACT: neutral, happy, sad, surprise, fear, disgust, anger, contempt).

Temporal metrics (Div, FRDist, FRSyn) see the scored frames joined across the removed blocks.

**Scaling.** No published table exists for this corpus. Printed values use DualTalk's publication factors
of the analogous component: ``expression`` those of FLAME ``exp`` (FD 1, P-FD 1, MSE 10, rPCC 100),
``head`` and ``gaze`` those of head ``pose`` (FD 100, P-FD 100, MSE 100, rPCC 10); the REACT line is
unscaled. Raw values are always kept beside the scaled ones.
"""

from __future__ import annotations

import warnings

import numpy as np

from dyadbench.errors import InputError
from dyadbench.metrics import dualtalk, react
from dyadbench.metrics.columns import ColumnSpec, SuiteColumns
from dyadbench.metrics.dtw import weighted_dtw_pairs
from dyadbench.motion import MotionLayout

SID_K = {"expression": 40, "head": 10, "gaze": 10}
MIN_FRAMES = max(SID_K.values())
EMOTION_GROUPS = ((0, 24, 1 / 24), (24, 26, 1.0), (26, 34, 1 / 8))
#: (name, header, higher_is_better, scale of expression, scale of head/gaze, printed)
_MOTION_METRICS = (("fd", "FD", False, 1.0, 1e2, True), ("pfd", "P-FD", False, 1.0, 1e2, True),
                   ("mse", "MSE", False, 10.0, 1e2, True), ("sid", "SID", True, 1.0, 1.0, True),
                   ("rpcc", "rPCC", False, 1e2, 10.0, True), ("var_pred", "Var", None, 1.0, 1.0, True),
                   ("var_gt", "Var-GT", None, 1.0, 1.0, False), ("div_pred", "Div", None, 1.0, 1.0, True),
                   ("div_gt", "Div-GT", None, 1.0, 1.0, False))
_EMOTION_METRICS = (("FRCorr", True), ("FRDist", False), ("FRVar", True), ("FRSyn", False))
MOTION_COMPONENTS = ("expression", "head", "gaze")
NOT_COMPUTED = {"FRDiv": "needs R >= 2 reactions per speaker (one deterministic prediction per agent here)",
                "FRDvs": "needs R >= 2 reactions per speaker (one deterministic prediction per agent here)",
                "FRRea": "needs rendered video"}


def _columns() -> tuple[ColumnSpec, ...]:
    cols = [ColumnSpec(f"{name}_{c}", f"{header} {c}", better, exp_scale if c == "expression" else head_scale,
                       table=printed)
            for name, header, better, exp_scale, head_scale, printed in _MOTION_METRICS for c in MOTION_COMPONENTS]
    return tuple(cols + [ColumnSpec(name, name, better) for name, better in _EMOTION_METRICS]
                 + [ColumnSpec("frames_scored", "frames scored", None, table=False),
                    ColumnSpec("frames_excluded", "frames excluded", None, table=False)])


#: Every key the suite may report (``gaze`` keys only for ``seamless-gaze``), ranked by FD expression.
COLUMNS = SuiteColumns("seamless", _columns(), primary="fd_expression")


def components(layout: MotionLayout) -> tuple[str, ...]:
    return tuple(c for c in MOTION_COMPONENTS if c in layout.components)


def keys(layout: MotionLayout) -> list[str]:
    """The per-item keys for ``layout``, in column order."""
    present = set(components(layout))
    return [c.key for c in COLUMNS.columns if c.key.rsplit("_", 1)[-1] in present
            or "_" not in c.key or c.key.startswith("frames_")]


def scored_frames(gt: np.ndarray, partner: np.ndarray) -> np.ndarray:
    """(T,) bool: frames where both the agent's and the partner's movement features are valid."""
    return (np.asarray(gt)[:, -1] > 0.5) & (np.asarray(partner)[:, -1] > 0.5)


def emotion_metrics(p: np.ndarray, g: np.ndarray, a: np.ndarray) -> dict[str, float]:
    """FRCorr, FRDist, FRVar, FRSyn of one prediction (T, 34) against its ground truth g and partner a."""
    pr, gr, ar = (np.ascontiguousarray(x, dtype=np.float32)[None] for x in (p, g, a))
    corr = react.fr_corr_per_reaction(pr[:, None], gr, np.array([0, 1], np.int64), np.array([0], np.int64))
    dist = weighted_dtw_pairs(pr.astype(np.float64), gr.astype(np.float64), [0], [0], EMOTION_GROUPS)
    return {"FRCorr": float(corr[0, 0]), "FRDist": float(dist[0]),
            "FRVar": float(react.time_variances(pr[:, None]).mean()),
            "FRSyn": float(react.fr_syn_offsets(pr[:, None], ar, all_reactions=False)[0])}


def item_metrics(pred: np.ndarray, gt: np.ndarray, partner: np.ndarray, layout: MotionLayout, *,
                 seed: int) -> dict[str, float]:
    """Every metric of one predicted agent (see the module docstring); keys :func:`keys` of ``layout``.

    ``seed`` seeds Div as in :func:`dyadbench.metrics.dualtalk.clip_metrics` (component i uses
    ``default_rng([seed, i])``). Raises :class:`InputError` when fewer than :data:`MIN_FRAMES` frames are scored.
    """
    for name, array in (("prediction", pred), ("ground truth", gt), ("partner", partner)):
        if array.ndim != 2 or array.shape[1] != layout.dim:
            raise InputError(name, f"expected (T, {layout.dim}) for layout {layout.name}, got shape {array.shape}")
    pred, gt, partner = dualtalk.truncate_to_shortest(*(np.asarray(x, np.float64) for x in (pred, gt, partner)))
    keep = scored_frames(gt, partner)
    scored = int(keep.sum())
    if scored < MIN_FRAMES:
        raise InputError(None, f"only {scored} frames valid for both participants; the suite needs {MIN_FRAMES}")
    pred, gt, partner = pred[keep], gt[keep], partner[keep]
    out: dict[str, float] = {}
    for i, c in enumerate(components(layout)):
        p, g, a = (layout.component(x, c) for x in (pred, gt, partner))
        with warnings.catch_warnings():
            warnings.filterwarnings("ignore", message="Number of distinct clusters")
            sid = dualtalk.sid(p, g, SID_K[c])
        out.update({f"fd_{c}": dualtalk.fd(p, g), f"pfd_{c}": dualtalk.pfd(p, g, a), f"mse_{c}": dualtalk.mse(p, g),
                    f"sid_{c}": sid, f"rpcc_{c}": dualtalk.rpcc(p, g, a), f"var_pred_{c}": dualtalk.variance(p),
                    f"var_gt_{c}": dualtalk.variance(g),
                    f"div_pred_{c}": dualtalk.diversity(p, np.random.default_rng([seed, i])),
                    f"div_gt_{c}": dualtalk.diversity(g, np.random.default_rng([seed, i]))})
    out.update(emotion_metrics(*(layout.component(x, "emotion34") for x in (pred, gt, partner))))
    out.update({"frames_scored": float(scored), "frames_excluded": float(len(keep) - scored)})
    return {k: out[k] for k in keys(layout)}
