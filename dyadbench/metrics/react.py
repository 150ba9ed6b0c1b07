"""The REACT 2023/2024 metric suite on 25-d emotion features: FRCorr, FRDist, FRDiv, FRVar, FRDvs, FRSyn.

Inputs (see ``metrics-react.md``): predictions P (N, R, T, 25) with R reactions per speaker sample,
speaker ground truth Sp (N, T, 25) in the same (mirrored) sample order, the real listener reactions
L (M, T, 25) and the appropriateness matrix S (N, M): ``S[k, j] == 1`` means the real listener reaction
j is appropriate for speaker k. Normally M = N and L[j] is sample j's own listener; a scorer that
leaves some samples' predictions out passes the rows of S of the samples it scores and keeps every
real reaction (M > N). Feature columns: 0-14 action units, 15-16 valence and arousal, 17-24
expression probabilities.

Like the official pipeline, which holds every array as float32, all inputs are rounded to float32;
the arithmetic is then float64. FRDist equals the official tslearn loop bit for bit (same DTW
operations, same sums); FRSyn is an average of integer offsets with the same float32 steps and matches
exactly; FRCorr, FRDiv, FRVar and FRDvs agree with a float64 loop evaluation of the same formulas to
~1e-12 relative (the official script's float32 ``torch.cdist`` for FRDiv/FRDvs and float32 statistics
for FRCorr differ from float64 by up to ~1e-6 relative).

FRRea (FID of rendered frames) needs FaceVerse, PIRender and the videos: it is not computed here and
is reported as such by the scorer (:data:`NOT_COMPUTED`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit, prange
from tqdm import tqdm

from dyadbench.errors import InputError
from dyadbench.metrics.ccc import max_ccc_over_neighbours, series_stats
from dyadbench.metrics.columns import ColumnSpec, SuiteColumns
from dyadbench.metrics.dtw import min_weighted_dtw
from dyadbench.metrics.tlcc import float32_mean, tlcc_offsets

DIM = 25
REACTIONS = 10
FRAMES = 750
#: FRDist's DTW groups: (start, stop, weight) = AUs, valence/arousal, expression probabilities
DTW_GROUPS = ((0, 15, 1 / 15), (15, 17, 1.0), (17, 25, 1 / 8))
#: rows of the prediction array processed at once (bounds memory to ~chunk * R * T * 25 float64)
ROW_CHUNK = 64
#: FRDist's rows per call: larger calls fill more SIMD lanes with pairs that share a reference
DTW_ROW_CHUNK = 512


@dataclass(frozen=True)
class MetricInfo:
    name: str
    higher_is_better: bool
    description: str


METRICS: tuple[MetricInfo, ...] = (
    MetricInfo("FRCorr", True, "appropriateness: sum over the R reactions of the max CCC with an appropriate "
                               "real reaction, mean over speakers (range about [-R, R])"),
    MetricInfo("FRDist", False, "appropriateness: sum over the R reactions of the min grouped DTW to an "
                                "appropriate real reaction, mean over speakers"),
    MetricInfo("FRDiv", True, "diversity among the R reactions to one speaker (S-MSE)"),
    MetricInfo("FRVar", True, "mean variance over time of every predicted feature (ddof=1)"),
    MetricInfo("FRDvs", True, "diversity of reaction i across speakers"),
    MetricInfo("FRSyn", False, "synchrony: mean |TLCC offset| in frames of reaction 0 to the speaker "
                               "(official)"),
    MetricInfo("FRSyn_all", False, "synchrony over all R reactions (the official serial variant)"),
)
METRIC_INFO = {m.name: m for m in METRICS}
KEYS = tuple(m.name for m in METRICS)
#: The suite's columns (:mod:`dyadbench.metrics.columns`), unscaled, in the challenge's order; ranked by
#: FRCorr (appropriateness, higher is better).
COLUMNS = SuiteColumns("react", tuple(ColumnSpec(m.name, m.name, m.higher_is_better) for m in METRICS),
                       primary="FRCorr")
HIGHER_IS_BETTER = {c.key: c.higher_is_better for c in COLUMNS.columns}
NOT_COMPUTED = {"FRRea": "realism (FID of rendered frames) needs FaceVerse, PIRender and the videos; "
                         "dyadbench scores the 25-d emotion features only"}


# --- validation -----------------------------------------------------------------------------------

def _as_float32(array, name: str, ndim: int) -> np.ndarray:
    a = np.asarray(array)
    if a.ndim != ndim or a.shape[-1] != DIM:
        want = "(N, R, T, 25)" if ndim == 4 else "(N, T, 25)"
        raise InputError(name, f"expected {want}, got shape {a.shape}")
    if a.dtype.kind not in "fiu":
        raise InputError(name, f"expected real numbers, got dtype {a.dtype}")
    a = a.astype(np.float32, copy=False)
    bad = a.size - int(np.count_nonzero(np.isfinite(a)))
    if bad:
        first = np.argwhere(~np.isfinite(a))[0]
        raise InputError(name, f"contains {bad} NaN/inf values (first at index {tuple(int(i) for i in first)})")
    return a


def neighbour_lists(neighbours: np.ndarray, name: str = "neighbours") -> tuple[np.ndarray, np.ndarray]:
    """CSR form (indptr, indices) of ``neighbours == 1``; a row without any neighbour is an error."""
    s = np.asarray(neighbours)
    if s.ndim != 2:
        raise InputError(name, f"expected an (N, M) matrix, got shape {s.shape}")
    selected = s == 1
    counts = selected.sum(axis=1)
    empty = np.flatnonzero(counts == 0)
    if len(empty):
        rows = ", ".join(str(int(r)) for r in empty[:10]) + (" …" if len(empty) > 10 else "")
        raise InputError(name, f"{len(empty)} row(s) have no neighbour (no entry equal to 1): row {rows}")
    indptr = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
    return indptr, np.nonzero(selected)[1].astype(np.int64)


def check_inputs(predictions, listener, speaker, neighbours, reactions: int | None = REACTIONS):
    """Validate shapes/values; return (P, L, Sp) float32 and the neighbour lists (indptr, indices).

    ``listener`` holds the M real reactions the columns of ``neighbours`` (N, M) refer to."""
    p = _as_float32(predictions, "predictions", 4)
    lst = _as_float32(listener, "listener", 3)
    sp = _as_float32(speaker, "speaker", 3)
    n, r, t, _ = p.shape
    if reactions is not None and r != reactions:
        raise InputError("predictions", f"expected {reactions} reactions per sample (axis 1), got {r}")
    if n == 0 or t < 2:
        raise InputError("predictions", f"need at least one sample and 2 frames, got shape {p.shape}")
    if sp.shape != (n, t, DIM):
        raise InputError("speaker", f"expected shape {(n, t, DIM)} to match the predictions, got {sp.shape}")
    if lst.shape[1:] != (t, DIM):
        raise InputError("listener", f"expected shape (M, {t}, {DIM}) to match the predictions, got {lst.shape}")
    if np.shape(neighbours) != (n, len(lst)):
        raise InputError("neighbours", f"expected shape {(n, len(lst))} for {n} samples and {len(lst)} real "
                                       f"reactions, got {np.shape(neighbours)}")
    return p, lst, sp, neighbour_lists(neighbours)


# --- metrics ----------------------------------------------------------------------------------------

def _row_chunks(n: int, size: int = ROW_CHUNK):
    for start in range(0, n, size):
        yield slice(start, min(start + size, n))


def _sum_over_reactions(per_reaction: np.ndarray) -> np.ndarray:
    """(N, R) -> (N,): sum over reactions in order, as the reference's ``+=`` loop."""
    total = np.zeros(per_reaction.shape[0])
    for i in range(per_reaction.shape[1]):
        total = total + per_reaction[:, i]
    return total


def _chunk_indptr(indptr: np.ndarray, rows: slice, reactions: int) -> np.ndarray:
    """CSR pointers of the queries (k, i) of rows k in ``rows``: each row's list repeated R times."""
    counts = np.repeat(np.diff(indptr[rows.start:rows.stop + 1]), reactions)
    return np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)


def fr_corr_per_reaction(p, lst, indptr, indices) -> np.ndarray:
    """(N, R): max over appropriate real reactions j of CCC(L[j], P[k, i])."""
    out = np.empty(p.shape[:2])
    listener_stats = series_stats(lst)
    for rows in _row_chunks(len(p)):
        sub_ptr = indptr[rows.start:rows.stop + 1]
        out[rows] = max_ccc_over_neighbours(p[rows], listener_stats, sub_ptr - sub_ptr[0],
                                            indices[sub_ptr[0]:sub_ptr[-1]])
    return out


def fr_corr(p, lst, indptr, indices) -> float:
    """FRCorr (higher is better).

    .. math:: \\mathrm{FRCorr} = \\frac{1}{N}\\sum_k \\sum_{i=0}^{R-1}
              \\max_{j: S_{kj}=1} \\mathrm{CCC}(L_j, P_{k,i})
    """
    return float(np.mean(_sum_over_reactions(fr_corr_per_reaction(p, lst, indptr, indices))))


def fr_dist_per_reaction(p, lst, indptr, indices, *, screen: bool = True, prune: bool = True,
                         threads: int | None = None, progress: bool = False) -> np.ndarray:
    """(N, R): min over appropriate real reactions j of the grouped DTW of P[k, i] and L[j]."""
    n, r = p.shape[:2]
    out = np.empty((n, r))
    refs = lst.astype(np.float64)
    bar = tqdm(total=n, desc="FRDist (DTW)", unit="sample", disable=not progress, leave=False)
    for rows in _row_chunks(n, DTW_ROW_CHUNK):
        ptr = _chunk_indptr(indptr, rows, r)
        cand = np.concatenate([np.tile(indices[indptr[k]:indptr[k + 1]], r) for k in range(rows.start, rows.stop)])
        queries = np.ascontiguousarray(p[rows]).reshape(-1, p.shape[2], DIM)  # float32, widened in the kernel
        values, _ = min_weighted_dtw(queries, refs, ptr, cand, DTW_GROUPS, screen=screen, prune=prune,
                                     threads=threads)
        out[rows] = values.reshape(-1, r)
        bar.update(rows.stop - rows.start)
    bar.close()
    return out


def fr_dist(p, lst, indptr, indices, *, screen: bool = True, prune: bool = True,
            threads: int | None = None) -> float:
    """FRDist (lower is better).

    .. math:: \\mathrm{FRDist} = \\frac{1}{N}\\sum_k \\sum_i \\min_{j: S_{kj}=1}
              \\Big(\\tfrac{1}{15}\\mathrm{DTW}(P^{AU}_{k,i}, L^{AU}_j) + \\mathrm{DTW}(P^{VA}_{k,i}, L^{VA}_j)
              + \\tfrac18\\mathrm{DTW}(P^{FE}_{k,i}, L^{FE}_j)\\Big)

    with exact DTW (:mod:`dyadbench.metrics.dtw`), one warping path per group. ``screen`` and ``prune``
    (:func:`~dyadbench.metrics.dtw.min_weighted_dtw`) change the running time only.
    """
    per = fr_dist_per_reaction(p, lst, indptr, indices, screen=screen, prune=prune, threads=threads)
    return float(np.mean(_sum_over_reactions(per)))


@njit(cache=True, parallel=True)
def _ordered_pair_sq_sum(stack):
    out = np.empty(stack.shape[0])
    n = stack.shape[1]
    for b in prange(stack.shape[0]):
        total = 0.0
        for f in range(stack.shape[2]):
            origin = np.float64(stack[b, 0, f])
            mean = 0.0
            for a in range(n):
                mean += np.float64(stack[b, a, f]) - origin
            mean /= n
            for a in range(n):
                dev = (np.float64(stack[b, a, f]) - origin) - mean
                total += dev * dev
        out[b] = 2.0 * n * total
    return out


def ordered_pair_sq_sum(stack: np.ndarray) -> np.ndarray:
    """sum over ordered pairs a != b of |s_a - s_b|^2 along axis 1 of ``stack`` (B, n, F) -> (B,).

    Uses the identity sum_{a != b} |s_a - s_b|^2 = 2 n sum_a |s_a - mean|^2 on values shifted by s_0
    (exactly 0 when all members are equal), in float64, one pass per sample.
    """
    return _ordered_pair_sq_sum(np.ascontiguousarray(stack))


def fr_div_per_sample(p) -> np.ndarray:
    """(N,): sum over ordered pairs i != j of |P[k,i] - P[k,j]|^2 / (R (R-1) T 25); zeros when R == 1."""
    n, r, t, d = p.shape
    if r == 1:
        return np.zeros(n)
    per = np.concatenate([ordered_pair_sq_sum(p[rows].reshape(rows.stop - rows.start, r, t * d))
                          for rows in _row_chunks(n)])
    return per / (r * (r - 1) * t * d)


def fr_div(p) -> float:
    """FRDiv / S-MSE (higher is better); 0 when R == 1.

    .. math:: \\mathrm{FRDiv} = \\frac{1}{N}\\sum_k \\frac{\\sum_{i \\ne j}\\lVert P_{k,i} - P_{k,j}\\rVert^2}
              {R(R-1)\\,T\\cdot 25}
    """
    return float(np.mean(fr_div_per_sample(p)))


def fr_var(p) -> float:
    """FRVar (higher is better): mean over samples, reactions and features of the variance over time.

    .. math:: \\mathrm{FRVar} = \\frac{1}{N R\\, 25}\\sum_{k,i,c} \\frac{1}{T-1}\\sum_t
              (P_{k,i,t,c} - \\bar P_{k,i,c})^2
    """
    return float(np.mean(time_variances(p)))


@njit(cache=True, parallel=True)
def _time_variances(p):
    n, r, t, d = p.shape
    out = np.empty((n, r, d))
    for k in prange(n):
        for i in range(r):
            mean = np.zeros(d)
            for s in range(t):
                for c in range(d):
                    mean[c] += np.float64(p[k, i, s, c])
            for c in range(d):
                mean[c] /= t
            acc = np.zeros(d)
            for s in range(t):
                for c in range(d):
                    dev = np.float64(p[k, i, s, c]) - mean[c]
                    acc[c] += dev * dev
            for c in range(d):
                out[k, i, c] = acc[c] / (t - 1)
    return out


def time_variances(p) -> np.ndarray:
    """(N, R, 25): unbiased (ddof=1) variance over time of each predicted feature, in float64."""
    return _time_variances(np.ascontiguousarray(p))


def fr_dvs(p) -> float:
    """FRDvs (higher is better): diversity of reaction i across speaker samples.

    .. math:: \\mathrm{FRDvs} = \\frac{\\sum_i \\sum_{k \\ne l}\\lVert P_{k,i} - P_{l,i}\\rVert^2}
              {N(N-1)\\,R\\;T\\cdot 25}
    """
    n, r, t, d = p.shape
    if n == 1:
        return 0.0
    total = sum(float(ordered_pair_sq_sum(p[:, i].reshape(1, n, t * d))[0]) for i in range(r))
    return total / (n * (n - 1) * r) / (t * d)


def fr_syn_offsets(p, sp, *, all_reactions: bool) -> np.ndarray:
    """TLCC offsets (N,) of reaction 0, or (N, R) of every reaction, against the speaker."""
    if not all_reactions:
        return tlcc_offsets(p[:, 0], sp)
    n, r = p.shape[:2]
    return tlcc_offsets(p.reshape(n * r, *p.shape[2:]), sp, np.repeat(np.arange(n), r)).reshape(n, r)


def fr_syn(p, sp, *, all_reactions: bool = False) -> float:
    """FRSyn (lower is better): float32 mean of TLCC offsets (:mod:`dyadbench.metrics.tlcc`).

    Official (default): reaction 0 only, one offset per speaker sample (the official parallel function
    returns inside its loop). ``all_reactions=True``: every reaction (the official serial function).
    """
    return float32_mean(fr_syn_offsets(p, sp, all_reactions=all_reactions).ravel())


def evaluate(predictions, listener, speaker, neighbours, *, reactions: int | None = REACTIONS,
             screen: bool = True, threads: int | None = None,
             progress: bool = False) -> tuple[dict[str, float], dict[str, np.ndarray]]:
    """:func:`score` plus each speaker sample's contribution: ``(metrics, per_sample)``.

    ``per_sample`` holds (N,) arrays whose mean is the metric: ``FRCorr`` and ``FRDist`` (sum over the
    reactions of the best value over neighbours), ``FRDiv``, ``FRVar`` (mean variance of the sample's
    reactions), ``FRSyn`` (TLCC offset of reaction 0) and ``FRSyn_all`` (mean offset of the sample's
    reactions; its mean over samples equals the metric up to float32 rounding). FRDvs has no per-sample form.
    """
    p, lst, sp, (indptr, indices) = check_inputs(predictions, listener, speaker, neighbours, reactions)
    corr = _sum_over_reactions(fr_corr_per_reaction(p, lst, indptr, indices))
    dist = _sum_over_reactions(fr_dist_per_reaction(p, lst, indptr, indices, screen=screen, threads=threads,
                                                    progress=progress))
    div = fr_div_per_sample(p)
    variances = time_variances(p)
    offsets = fr_syn_offsets(p, sp, all_reactions=True)
    metrics = {
        "FRCorr": float(np.mean(corr)),
        "FRDist": float(np.mean(dist)),
        "FRDiv": float(np.mean(div)),
        "FRVar": float(np.mean(variances)),
        "FRDvs": fr_dvs(p),
        "FRSyn": float32_mean(offsets[:, 0]),
        "FRSyn_all": float32_mean(offsets.ravel()),
    }
    var = variances.mean(axis=(1, 2))
    per_sample = {"FRCorr": corr, "FRDist": dist, "FRDiv": div, "FRVar": var,
                  "FRSyn": offsets[:, 0].astype(np.float64), "FRSyn_all": offsets.mean(axis=1, dtype=np.float64)}
    return metrics, per_sample


def score(predictions, listener, speaker, neighbours, *, reactions: int | None = REACTIONS,
          screen: bool = True, threads: int | None = None) -> dict[str, float]:
    """Every metric of the suite: a dict keyed ``FRCorr FRDist FRDiv FRVar FRDvs FRSyn FRSyn_all``.

    ``predictions`` (N, R, T, 25), ``speaker`` (N, T, 25), ``listener`` (M, T, 25) (normally M = N: each
    sample's own listener), ``neighbours`` (N, M) of 0/1.
    Raises :class:`InputError` for wrong shapes, a wrong R (``reactions=None`` accepts any), NaN/inf
    values, or a neighbour row without any 1 (naming the row). ``screen`` (the certified float32 screen
    of :func:`dyadbench.metrics.dtw.min_weighted_dtw`; same values either way) and ``threads`` only
    change FRDist's running time. Higher is better for FRCorr, FRDiv, FRVar, FRDvs; lower for FRDist
    and FRSyn (see :data:`HIGHER_IS_BETTER`).
    """
    return evaluate(predictions, listener, speaker, neighbours, reactions=reactions, screen=screen,
                    threads=threads)[0]
