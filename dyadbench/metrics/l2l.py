"""The Learning2Listen-line suite (L2L follow-ups, SFMS Table I): L2, FD, P-FD, Var, SI, rPCC.

No public script holds the original paper's metrics; the public variants agree on the Fréchet helper
and differ in details. dyadbench implements one documented variant in which every choice is a named
parameter of :class:`L2LParams`, recorded in each result. Per component c (``exp`` 50 dims, ``pose``
= global head rotation 3 dims, ``jaw`` 3 dims) over the listener predictions p, ground truth g and the
speaker's motion a (all (T, 56) flame56 sequences of a split):

- **L2** (lower is better): mean squared error over all frames and dims of the split
  (:func:`dyadbench.metrics.dualtalk.mse` of the pooled frames).
- **FD** (lower): Fréchet distance per sequence, averaged over sequences
  (:func:`dyadbench.metrics.dualtalk.fd`).
- **P-FD** (lower): paired Fréchet distance per sequence on [speaker, listener] features (speaker
  first), averaged (:func:`dyadbench.metrics.dualtalk.pfd`).
- **Var**: mean over dims of the variance over the pooled frames (ddof=0) of the prediction, reported
  beside the ground truth's (``var_gt``); closer to the ground truth is better.
- **SI** (Shannon index, higher is more diverse): k-means (``KMeans(k, random_state=0, n_init="auto")``)
  fitted on all ground-truth frames of the split, labels of the predicted frames, entropy
  -sum q log2(q + 1e-6) (:mod:`dyadbench.metrics.entropy`); ``si_gt`` labels the ground truth itself
  (the "GT" row of the SFMS table). k: 15 exp, 9 pose (SFMS), 9 jaw.
- **rPCC** (lower): |corr(g, a) - corr(p, a)| on the flattened pooled split
  (:func:`dyadbench.metrics.dualtalk.rpcc`).

P-FD and rPCC need the speaker's motion (:data:`NEEDS_PARTNER`). A sequence given without it (``a`` is
None) has P-FD NaN and is left out of both: P-FD is the mean over the other sequences, rPCC is pooled over
them (NaN when no sequence has its speaker); every other metric uses every sequence.
"""

from __future__ import annotations

import warnings
from dataclasses import asdict, dataclass, field

import numpy as np

from dyadbench.errors import InputError
from dyadbench.metrics import dualtalk
from dyadbench.metrics.columns import ColumnSpec, SuiteColumns
from dyadbench.metrics.entropy import fit_kmeans, occupancy_entropy
from dyadbench.motion import FLAME56


@dataclass(frozen=True)
class L2LParams:
    """Every choice of the suite (recorded in results)."""

    components: tuple[str, ...] = ("exp", "pose", "jaw")
    si_k: dict[str, int] = field(default_factory=lambda: {"exp": 15, "pose": 9, "jaw": 9})
    kmeans_random_state: int = 0
    l2: str = "mean squared error over the pooled frames and dims of the split"
    fd: str = "Fréchet distance per sequence, mean over sequences"
    pfd: str = "paired Fréchet distance per sequence on [speaker, listener] (speaker first), mean over sequences"
    var: str = "mean over dims of the variance over the pooled frames (ddof=0)"
    si: str = "k-means fitted on the pooled ground-truth frames, labels of the predicted frames, bits"
    rpcc: str = "|corr(gt, speaker) - corr(pred, speaker)| of the flattened pooled split"

    def as_dict(self) -> dict:
        return asdict(self)


#: metric name -> higher_is_better (None: compare with the ground truth's value; ``var_gt`` and ``si_gt``
#: are the ground truth's own values, references rather than scores)
HIGHER_IS_BETTER = {"l2": False, "fd": False, "pfd": False, "var": None, "var_gt": None, "si": True,
                    "si_gt": None, "rpcc": False}
METRIC_NAMES = tuple(HIGHER_IS_BETTER)
HEADERS = {"l2": "L2", "fd": "FD", "pfd": "P-FD", "var": "Var", "var_gt": "Var-GT", "si": "SI", "si_gt": "SI-GT",
           "rpcc": "rPCC"}
PER_SEQUENCE = ("l2", "fd", "pfd")
#: Metrics computed from the speaker's motion (the listener's partner): not computable without it.
NEEDS_PARTNER = ("pfd", "rpcc")


def keys(params: L2LParams = L2LParams()) -> list[str]:
    return [f"{m}_{c}" for m in METRIC_NAMES for c in params.components]


def partner_keys(params: L2LParams = L2LParams()) -> list[str]:
    """The keys of :data:`NEEDS_PARTNER` (P-FD and rPCC per component), in :func:`keys` order."""
    return [k for k in keys(params) if k.rsplit("_", 1)[0] in NEEDS_PARTNER]


def cut(p: np.ndarray, g: np.ndarray, a: np.ndarray | None) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """One sequence's prediction, ground truth and speaker (None: missing) cut to their shortest length."""
    if a is None:
        return (*dualtalk.truncate_to_shortest(p, g), None)
    return dualtalk.truncate_to_shortest(p, g, a)


#: Jaw and pose (axis-angle rotations) are ~1e-3 of exp in every size-like metric; printed ×10³ so that two
#: decimals show them (dyadbench's choice: no public L2L table prints them).
SMALL_COMPONENT_SCALE = {"jaw": 1e3, "pose": 1e3}
SCALED_METRICS = ("l2", "fd", "pfd", "var", "var_gt")
#: ground-truth values printed as the tables' ground-truth row under the prediction's column
REFERENCES = {"var_gt": "var", "si_gt": "si"}


def _column(m: str, c: str) -> ColumnSpec:
    scale = SMALL_COMPONENT_SCALE.get(c, 1.0) if m in SCALED_METRICS else 1.0
    reference = REFERENCES.get(m)
    return ColumnSpec(f"{m}_{c}", f"{HEADERS[m]} {c}", HIGHER_IS_BETTER[m], scale, table=reference is None,
                      reference=None if reference is None else f"{reference}_{c}")


#: The suite's columns (:mod:`dyadbench.metrics.columns`) in :func:`keys` order (SFMS Table I's metrics,
#: each per component; Var-GT and SI-GT as its ground-truth row); ranked by L2 exp (lower is better).
COLUMNS = SuiteColumns("l2l", tuple(_column(m, c) for m in METRIC_NAMES for c in L2LParams().components),
                       primary="l2_exp")


def _check(sequences: list[np.ndarray | None], name: str) -> list[np.ndarray | None]:
    out = []
    for i, s in enumerate(sequences):
        if s is None and name == "speaker":
            out.append(None)
            continue
        a = np.asarray(s, dtype=np.float64)
        if a.ndim != 2 or a.shape[1] != FLAME56.dim or a.shape[0] < 2:
            raise InputError(f"{name} {i}", f"expected (T >= 2, {FLAME56.dim}), got shape {a.shape}")
        if not np.isfinite(a).all():
            raise InputError(f"{name} {i}", "contains NaN/inf values")
        out.append(a)
    return out


def sequence_metrics(p: np.ndarray, g: np.ndarray, a: np.ndarray | None, params: L2LParams = L2LParams()) -> dict:
    """L2, FD and P-FD of one sequence, per component (``l2_exp``, ``fd_pose``, ...); P-FD is NaN when the
    speaker's motion ``a`` is None (missing)."""
    out = {}
    for c in params.components:
        pc, gc = FLAME56.component(p, c), FLAME56.component(g, c)
        out[f"l2_{c}"] = dualtalk.mse(pc, gc)
        out[f"fd_{c}"] = dualtalk.fd(pc, gc)
        out[f"pfd_{c}"] = dualtalk.pfd(pc, gc, FLAME56.component(a, c)) if a is not None else float("nan")
    return out


def split_metrics(preds: list[np.ndarray], gts: list[np.ndarray], speakers: list[np.ndarray],
                  params: L2LParams = L2LParams(),
                  per_sequence: list[dict] | None = None) -> tuple[dict[str, float], list[dict]]:
    """The suite over a split: ``(metrics, per_sequence)``; ``metrics`` keyed :func:`keys`.

    Sequence i's prediction, ground truth and speaker are cut to their shortest common length. A speaker
    given as None (missing) leaves that sequence out of P-FD and rPCC (module docstring).
    ``per_sequence``: the :func:`sequence_metrics` of those cut sequences when the caller computed them
    already (a scorer leaving out sequences whose Fréchet distance is undefined).
    """
    preds, gts, speakers = (_check(x, n) for x, n in ((preds, "prediction"), (gts, "ground truth"),
                                                       (speakers, "speaker")))
    if not (len(preds) == len(gts) == len(speakers)) or not preds:
        raise InputError(None, f"need as many predictions, ground truths and speakers (>= 1), got "
                               f"{len(preds)}, {len(gts)}, {len(speakers)}")
    triples = [cut(p, g, a) for p, g, a in zip(preds, gts, speakers)]
    if per_sequence is None:
        per_sequence = [sequence_metrics(p, g, a, params) for p, g, a in triples]
    pooled = [np.concatenate([t[i] for t in triples]) for i in range(2)]
    paired = [t for t in triples if t[2] is not None]
    with_speaker = [np.concatenate([t[i] for t in paired]) for i in range(3)] if paired else None
    metrics: dict[str, float] = {}
    for c in params.components:
        p, g = (FLAME56.component(x, c) for x in pooled)
        metrics[f"l2_{c}"] = dualtalk.mse(p, g)
        metrics[f"fd_{c}"] = float(np.mean([s[f"fd_{c}"] for s in per_sequence]))
        pfd = [s[f"pfd_{c}"] for s, t in zip(per_sequence, triples) if t[2] is not None]
        metrics[f"pfd_{c}"] = float(np.mean(pfd)) if pfd else float("nan")
        metrics[f"var_{c}"] = dualtalk.variance(p)
        metrics[f"var_gt_{c}"] = dualtalk.variance(g)
        k = params.si_k[c]
        with warnings.catch_warnings():
            warnings.filterwarnings("ignore", message="Number of distinct clusters")
            model = fit_kmeans(g, k, params.kmeans_random_state)
        metrics[f"si_{c}"] = occupancy_entropy(model.predict(p), k)
        metrics[f"si_gt_{c}"] = occupancy_entropy(model.predict(g), k)
        metrics[f"rpcc_{c}"] = (dualtalk.rpcc(*(FLAME56.component(x, c) for x in with_speaker))
                                if with_speaker is not None else float("nan"))
    return {k: metrics[k] for k in keys(params)}, per_sequence
