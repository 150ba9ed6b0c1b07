"""The DualTalk/TIMAR metric suite: FD, P-FD, MSE, SID (both orientations), rPCC, STS, Var, Div.

Implements the arithmetic of the DualTalk and TIMAR metric scripts as the spec
``metrics-dualtalk.md`` describes it: every metric is computed per clip and per FLAME component
(exp 50 | jaw 3 | pose 3), then averaged over clips by the scorer. All functions are pure (arrays
in, numbers out). ``p`` is the prediction, ``g`` the agent's ground truth and ``a`` the partner's
("anchor") ground truth, each (T, d) for one component after truncation to the shortest length.

Differences from the reference scripts, all deliberate and documented:

- diversity draws its frame indices from a seeded :class:`numpy.random.Generator` (the reference
  uses the unseeded global RNG), the same frame pairs for the prediction and the ground truth of a
  clip and component (so an exact copy of the ground truth has Div = Div-GT); below
  :data:`DIVERSITY_TIMES` frames it is NaN instead of crashing;
- both SID orientations are reported, as ``sid`` (DualTalk's: k-means fitted on the prediction,
  ground truth labelled) and ``sid_gtfit`` (fitted on the ground truth, prediction labelled; called
  ``sid`` in TIMAR's script).

Agreement with the reference: ``benchmarks/bench_score_dualtalk.py`` scores a DualTalk-sized set
with a straightforward implementation of the spec beside dyadbench. Every metric is identical (max
abs difference 0) under the same BLAS thread count; with a multi-threaded BLAS, P-FD exp differs by
~1e-13 (the summation order of the 100x100 matrix products changes). Arithmetic is float64
throughout (ground truth and predictions are converted on load). Not checked: the published
scripts' own code; if they compute on the float32 arrays as loaded, their values differ from these
at the float32 round-off level (~1e-7 relative), and k-means labels (SID) may differ slightly.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

from dyadbench.errors import InputError
from dyadbench.metrics.columns import ColumnSpec, SuiteColumns
from dyadbench.metrics.entropy import kmeans_entropy
from dyadbench.metrics.frechet import frechet_between
from dyadbench.motion import FLAME56, FLAME_COMPONENTS

SID_K = {"exp": 40, "jaw": 10, "pose": 10}
STS_SCALE = 0.1
DIVERSITY_TIMES = 100
MIN_FRAMES = max(SID_K.values())  # k-means with k clusters needs at least k frames


@dataclass(frozen=True)
class MetricInfo:
    """One metric of the suite, as reported per component (``<name>_<component>`` keys).

    ``higher_is_better`` is None for descriptive statistics (variance, diversity), which are judged
    by their closeness to the ground-truth value rather than ordered. ``scale`` is the publication
    factor per component (printed value = raw × scale); ``in_paper`` marks the columns of the
    DualTalk/TIMAR tables; ``needs_partner`` marks the metrics computed from the partner's ground truth
    (not computable for a clip whose partner's ground truth is missing).
    """

    name: str
    header: str
    higher_is_better: bool | None
    scale: dict[str, float]
    in_paper: bool
    description: str
    needs_partner: bool = False

    def keys(self) -> list[str]:
        return [f"{self.name}_{c}" for c in FLAME_COMPONENTS]


def _per_component(exp: float, jaw: float, pose: float) -> dict[str, float]:
    return {"exp": exp, "jaw": jaw, "pose": pose}


_UNSCALED = _per_component(1.0, 1.0, 1.0)

METRICS: tuple[MetricInfo, ...] = (
    MetricInfo("fd", "FD", False, _per_component(1.0, 1e3, 1e2), True,
               "Fréchet distance between Gaussians fitted to prediction and ground-truth frames"),
    MetricInfo("pfd", "P-FD", False, _per_component(1.0, 1e3, 1e2), True,
               "Paired Fréchet distance on [partner, agent] features", needs_partner=True),
    MetricInfo("mse", "MSE", False, _per_component(10.0, 1e3, 1e2), True,
               "Mean squared error against the ground truth"),
    MetricInfo("sid", "SID", True, _UNSCALED, True,
               "k-means occupancy entropy, k-means fitted on the prediction, ground truth labelled (DualTalk)"),
    MetricInfo("sid_gtfit", "SID-gtfit", True, _UNSCALED, False,
               "k-means occupancy entropy, fitted on the ground truth, prediction labelled (TIMAR 'sid')"),
    MetricInfo("rpcc", "rPCC", False, _per_component(1e2, 10.0, 10.0), True,
               "Residual Pearson correlation with the partner", needs_partner=True),
    MetricInfo("sts", "STS", False, _UNSCALED, False,
               "Velocity difference to the ground truth (sqrt of summed squares / 0.1)"),
    MetricInfo("var_pred", "Var", None, _UNSCALED, False, "Mean per-dimension variance of the prediction"),
    MetricInfo("var_gt", "Var-GT", None, _UNSCALED, False, "Mean per-dimension variance of the ground truth"),
    MetricInfo("div_pred", "Div", None, _UNSCALED, False, "Mean distance between random frame pairs, prediction"),
    MetricInfo("div_gt", "Div-GT", None, _UNSCALED, False, "Mean distance between random frame pairs, ground truth"),
)
METRIC_INFO = {m.name: m for m in METRICS}

#: Per-clip result keys in their canonical order (the columns of ``per_clip.csv``).
KEYS: tuple[str, ...] = tuple(k for m in METRICS for k in m.keys())

#: Per-clip keys computed from the partner's ground truth (P-FD, rPCC): NaN when it is missing.
PARTNER_KEYS: tuple[str, ...] = tuple(k for m in METRICS if m.needs_partner for k in m.keys())

#: Metric names in the column order of the DualTalk/TIMAR tables, then dyadbench's extra columns.
PAPER_ORDER: tuple[str, ...] = (tuple(m.name for m in METRICS if m.in_paper)
                                + tuple(m.name for m in METRICS if not m.in_paper))

#: The suite's columns (:mod:`dyadbench.metrics.columns`) in :data:`PAPER_ORDER`: the DualTalk/TIMAR
#: table columns are printed in the paper layout, the others kept in results and ``long.csv``; ranked
#: by FD exp (lower is better), the tables' first column.
COLUMNS = SuiteColumns("dualtalk", tuple(
    ColumnSpec(key, f"{METRIC_INFO[name].header} {c}", METRIC_INFO[name].higher_is_better,
               METRIC_INFO[name].scale[c], table=METRIC_INFO[name].in_paper)
    for name in PAPER_ORDER for key, c in zip(METRIC_INFO[name].keys(), FLAME_COMPONENTS)), primary="fd_exp")

#: Publication scale factor of every key.
SCALE: dict[str, float] = {c.key: c.scale for c in COLUMNS.columns}

#: higher_is_better of every key (None: descriptive statistic, compare with the ground-truth value).
HIGHER_IS_BETTER: dict[str, bool | None] = {c.key: c.higher_is_better for c in COLUMNS.columns}


def fd(p: np.ndarray, g: np.ndarray) -> float:
    """Fréchet distance (lower is better) between Gaussians fitted to the frames of p and g.

    .. math:: \\mathrm{FD} = \\lVert\\mu_p-\\mu_g\\rVert^2 + \\operatorname{tr}\\Sigma_p
              + \\operatorname{tr}\\Sigma_g - 2\\operatorname{tr}\\sqrt{\\Sigma_p\\Sigma_g}

    with frame means and unbiased covariances (``np.cov(x, rowvar=False)``) and
    ``scipy.linalg.sqrtm`` of the product (see :func:`dyadbench.metrics.frechet.frechet_distance`).
    """
    return frechet_between(p, g)


def pfd(p: np.ndarray, g: np.ndarray, a: np.ndarray) -> float:
    """Paired Fréchet distance (lower is better): FD between [a, g] and [a, p] (partner first).

    .. math:: \\mathrm{P\\text{-}FD} = \\mathrm{FD}\\big([a_t, g_t]_t,\\ [a_t, p_t]_t\\big)

    where :math:`[a_t, x_t]` concatenates the partner's and the agent's features of frame t (2d dims).
    """
    return frechet_between(np.concatenate([a, g], axis=1), np.concatenate([a, p], axis=1))


def mse(p: np.ndarray, g: np.ndarray) -> float:
    """Mean squared error (lower is better) over all frames and dims.

    .. math:: \\mathrm{MSE} = \\frac{1}{Td}\\sum_{t,j}(p_{tj}-g_{tj})^2
    """
    return float(np.mean((p - g) ** 2))


def sid(p: np.ndarray, g: np.ndarray, k: int) -> float:
    """SID in DualTalk's orientation (higher is better): k-means fitted on p, labels of g.

    .. math:: \\mathrm{SID} = -\\sum_{i=1}^{k} q_i\\log_2(q_i+10^{-6}),\\quad
              q_i = \\tfrac{1}{T}\\big|\\{t : c_p(g_t)=i\\}\\big|

    where :math:`c_p` assigns a frame to the nearest centroid of
    ``KMeans(n_clusters=k, random_state=0, n_init="auto")`` fitted on the frames of p.
    In [-log2(1 + 1e-6), log2 k]: the 1e-6 makes a single occupied cluster score -1.4e-6, not 0.
    """
    return kmeans_entropy(fit_on=p, label=g, k=k)


def sid_gtfit(p: np.ndarray, g: np.ndarray, k: int) -> float:
    """SID in the other orientation (TIMAR's ``sid``): k-means fitted on g, labels of p.

    .. math:: \\mathrm{SID}_{gt} = -\\sum_{i=1}^{k} q_i\\log_2(q_i+10^{-6}),\\quad
              q_i = \\tfrac{1}{T}\\big|\\{t : c_g(p_t)=i\\}\\big|

    Same k-means settings and range as :func:`sid`; higher is better.
    """
    return kmeans_entropy(fit_on=g, label=p, k=k)


def _pearson(x: np.ndarray, y: np.ndarray) -> float:
    with np.errstate(invalid="ignore", divide="ignore"):
        return float(np.corrcoef(x.flatten(), y.flatten())[0, 1])


def rpcc(p: np.ndarray, g: np.ndarray, a: np.ndarray) -> float:
    """Residual Pearson correlation (lower is better): how far p's correlation with the partner is
    from the ground truth's.

    .. math:: \\mathrm{rPCC} = \\big|\\,\\rho(\\mathrm{vec}\\,g, \\mathrm{vec}\\,a)
              - \\rho(\\mathrm{vec}\\,p, \\mathrm{vec}\\,a)\\,\\big|

    with Pearson's :math:`\\rho` (``np.corrcoef``) of the flattened (T·d) arrays. In [0, 2]; 0 for
    p = g. NaN when p, g or a is constant (the correlation is undefined).
    """
    return abs(_pearson(g, a) - _pearson(p, a))


def sts(p: np.ndarray, g: np.ndarray) -> float:
    """Smoothness/velocity discrepancy (lower is better).

    .. math:: \\mathrm{STS} = \\sqrt{\\sum_{t\\ge1}\\sum_j
              \\frac{\\big((p_{t,j}-p_{t-1,j})-(g_{t,j}-g_{t-1,j})\\big)^2}{0.1}}
    """
    diff = np.diff(p, axis=0) - np.diff(g, axis=0)
    return float(np.sqrt(np.sum(diff ** 2 / STS_SCALE)))


def variance(x: np.ndarray) -> float:
    """Mean over dims of the per-dim variance over frames (ddof=0).

    .. math:: \\mathrm{Var} = \\frac{1}{d}\\sum_j \\frac{1}{T}\\sum_t (x_{tj}-\\bar x_j)^2
    """
    return float(np.mean(np.var(x, axis=0)))


def diversity(x: np.ndarray, rng: np.random.Generator, times: int = DIVERSITY_TIMES) -> float:
    """Mean Euclidean distance between ``times`` random frame pairs.

    .. math:: \\mathrm{Div} = \\frac{1}{n}\\sum_{i=1}^{n}\\lVert x_{u_i} - x_{v_i}\\rVert_2

    with u = ``rng.choice(T, n, replace=False)`` drawn first, then v likewise (n = ``times`` = 100).
    NaN when T < n (the reference script would crash): there are not n distinct frames to draw.
    """
    n_frames = x.shape[0]
    if n_frames < times:
        return float("nan")
    first = rng.choice(n_frames, times, replace=False)
    second = rng.choice(n_frames, times, replace=False)
    return float(np.mean(np.linalg.norm(x[first] - x[second], axis=1)))


def truncate_to_shortest(*arrays: np.ndarray) -> tuple[np.ndarray, ...]:
    """Cut every array to the smallest number of frames among them (as the reference does)."""
    n = min(a.shape[0] for a in arrays)
    return tuple(a[:n] for a in arrays)


def clip_metrics(pred: np.ndarray, gt: np.ndarray, partner: np.ndarray | None, *,
                 seed: int) -> dict[str, float]:
    """Every metric of the suite for one predicted agent: a dict keyed exactly :data:`KEYS`.

    ``pred``, ``gt`` and ``partner`` are (T, 56) [exp | jaw | pose]; they are truncated to the shortest
    length first. ``partner=None`` (its ground truth is missing): the partner-based keys
    (:data:`PARTNER_KEYS`, P-FD and rPCC) are NaN, every other key is computed as usual. ``seed`` seeds the diversity draws: component number i (exp 0, jaw 1, pose 2) uses
    ``numpy.random.default_rng([seed, i])`` for the prediction and a second, identically seeded
    generator for the ground truth, so both are measured on the same frame pairs. The scorer passes
    ``derive_seed(run_seed, stem)``.
    Raises :class:`InputError` for fewer than :data:`MIN_FRAMES` common frames (SID needs k frames).
    """
    given = (("prediction", pred), ("ground truth", gt)) + ((("partner", partner),) if partner is not None else ())
    for name, array in given:
        if array.ndim != 2 or array.shape[1] != FLAME56.dim:
            raise InputError(name, f"expected (T, {FLAME56.dim}), got shape {array.shape}")
    arrays = truncate_to_shortest(*(np.asarray(x, dtype=np.float64) for _, x in given))
    pred, gt = arrays[:2]
    partner = arrays[2] if partner is not None else None
    if pred.shape[0] < MIN_FRAMES:
        raise InputError(None, f"only {pred.shape[0]} common frames; the suite needs at least {MIN_FRAMES}")
    values: dict[str, dict[str, float]] = {m.name: {} for m in METRICS}
    for i, c in enumerate(FLAME_COMPONENTS):
        p, g = (FLAME56.component(x, c) for x in (pred, gt))
        a = FLAME56.component(partner, c) if partner is not None else None
        k = SID_K[c]
        values["fd"][c] = fd(p, g)
        values["pfd"][c] = pfd(p, g, a) if a is not None else float("nan")
        values["mse"][c] = mse(p, g)
        with warnings.catch_warnings():
            # Fewer distinct frames than clusters (e.g. a constant prediction) is valid input here.
            warnings.filterwarnings("ignore", message="Number of distinct clusters")
            values["sid"][c] = sid(p, g, k)
            values["sid_gtfit"][c] = sid_gtfit(p, g, k)
        values["rpcc"][c] = rpcc(p, g, a) if a is not None else float("nan")
        values["sts"][c] = sts(p, g)
        values["var_pred"][c] = variance(p)
        values["var_gt"][c] = variance(g)
        values["div_pred"][c] = diversity(p, np.random.default_rng([seed, i]))
        values["div_gt"][c] = diversity(g, np.random.default_rng([seed, i]))
    return {f"{name}_{c}": values[name][c] for name in (m.name for m in METRICS) for c in FLAME_COMPONENTS}
