"""Throughput of DualTalk-suite scoring on a DualTalk-sized test set, against a straightforward scorer.

The set is generated in memory: 533 dialogues -> 1066 predicted agents of ~780 frames (700-860) at
FLAME-like magnitudes (expression coefficients of order 0.5 with a per-person offset, jaw opening
~0.1 rad, head rotation ~0.05 rad; smooth AR(1) motion). Each prediction is a noisy, partly
independent version of the agent's ground truth.

The reference in the same run is a straightforward per-clip implementation of the spec, written
below as plain loops over clips and components in one process with the default BLAS/OpenMP threads,
every metric computed on its own and independently of dyadbench's code: the Fréchet distance in its
symmetric form by eigendecompositions (dyadbench uses scipy's ``sqrtm`` of S1 S2), SID's labels as the
nearest centroid of the spec's ``KMeans(k, random_state=0, n_init="auto")`` by explicit distances, and
diversity's pair distances one by one (with dyadbench's seeding rule in place of the reference's
unseeded RNG). It is timed twice: with default threads and under a 1-thread limit, so the table
separates the gain of thread limiting from that of worker processes. dyadbench's ``score_arrays``
is timed with ``jobs=1`` and ``jobs=2``. The max abs difference of every metric against the
reference (and between jobs=1 and jobs=2) is printed.

    python benchmarks/bench_score_dualtalk.py                        # 1066 agents, reference on 100
    python benchmarks/bench_score_dualtalk.py --agents 200 --reference-agents 40   # quick look

Both write benchmarks/results/score_dualtalk.{json,md} (``--out`` elsewhere).

The reference runs on the first ``--reference-agents`` agents only (it can be very slow with default
threads on a busy machine); its clips/s is compared with dyadbench's clips/s on the full set.
"""

from __future__ import annotations

import math
import os
import platform
import sys
from pathlib import Path

import click
import numpy as np
from scipy.signal import lfilter
from sklearn.cluster import KMeans
from threadpoolctl import threadpool_limits

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from output import RESULTS, Transcript, write_result  # noqa: E402  (benchmarks/output.py)
from timing import timed  # noqa: E402  (benchmarks/timing.py)

from dyadbench.metrics.dualtalk import KEYS  # noqa: E402
from dyadbench.scoring.dualtalk import score_arrays  # noqa: E402
from dyadbench.scoring.report import ScoreItem  # noqa: E402
from dyadbench.seeding import derive_seed  # noqa: E402

# --- a DualTalk-sized set in memory ------------------------------------------------------------------

EXP_STD = np.linspace(0.74, 0.36, 50)
JAW_STD = np.array([0.05, 0.015, 0.015])
POSE_STD = np.array([0.06, 0.06, 0.04])


def _ar1(rng: np.random.Generator, frames: int, std: np.ndarray, alpha: float) -> np.ndarray:
    """Stationary AR(1) noise (frames, len(std)) with per-dim std ``std`` and smoothness ``alpha``."""
    noise = rng.normal(size=(frames, std.size))
    noise[0] /= np.sqrt(1 - alpha ** 2)  # start in the stationary distribution
    return lfilter([np.sqrt(1 - alpha ** 2)], [1.0, -alpha], noise, axis=0) * std


def _person(rng: np.random.Generator, frames: int) -> np.ndarray:
    offset = np.r_[rng.normal(0, 0.4, 50), [0.1, 0.0, 0.0], rng.normal(0.15, 0.05, 3)]
    motion = np.concatenate([_ar1(rng, frames, EXP_STD, 0.97), _ar1(rng, frames, JAW_STD, 0.9),
                             _ar1(rng, frames, POSE_STD, 0.95)], axis=1)
    return (offset + motion).astype(np.float32)


def make_set(agents: int, seed: int = 0) -> list[ScoreItem]:
    """``agents`` predicted agents, two per dialogue (speaker1 <-> speaker2 partners)."""
    rng = np.random.default_rng(seed)
    items = []
    for dialogue in range((agents + 1) // 2):
        frames = int(rng.integers(700, 861))
        people = [_person(rng, frames), _person(rng, frames)]
        for k in (1, 2):
            gt, partner = people[k - 1], people[2 - k]
            pred = 0.7 * gt + 0.7 * (_person(rng, frames) - gt.mean(axis=0)) + 0.3 * gt.mean(axis=0)
            items.append(ScoreItem(f"dlg{dialogue:04d}_speaker{k}", pred.astype(np.float32), gt, partner))
    return items[:agents]


# --- the straightforward reference: the spec as plain per-clip loops -----------------------------------

COMPONENTS = (("exp", slice(0, 50), 40), ("jaw", slice(50, 53), 10), ("pose", slice(53, 56), 10))


def ref_frechet(x: np.ndarray, y: np.ndarray) -> float:
    """Symmetric form: |mu_x - mu_y|^2 + tr Sx + tr Sy - 2 tr (Sx^1/2 Sy Sx^1/2)^1/2, with unbiased
    covariances; both roots from eigendecompositions of symmetric matrices (negative round-off clipped)."""
    mx, my = x.mean(axis=0), y.mean(axis=0)
    sx = (x - mx).T @ (x - mx) / (len(x) - 1)
    sy = (y - my).T @ (y - my) / (len(y) - 1)
    w, v = np.linalg.eigh(sx)
    root_x = (v * np.sqrt(np.clip(w, 0, None))) @ v.T
    inner = np.linalg.eigvalsh(root_x @ sy @ root_x)
    return float(np.sum((mx - my) ** 2) + np.trace(sx) + np.trace(sy) - 2 * np.sum(np.sqrt(np.clip(inner, 0, None))))


def ref_sid(fit_on: np.ndarray, label: np.ndarray, k: int) -> float:
    """-sum_i q_i log2(q_i + 1e-6), q_i = share of ``label`` rows whose nearest centroid (squared Euclidean
    distance) of the k-means fitted on ``fit_on`` is i."""
    centres = KMeans(n_clusters=k, random_state=0, n_init="auto").fit(fit_on).cluster_centers_
    nearest = np.argmin(((label[:, None, :] - centres[None, :, :]) ** 2).sum(axis=2), axis=1)
    q = np.array([np.count_nonzero(nearest == i) for i in range(k)]) / len(label)
    return float(-np.sum(q * np.log2(q + 1e-6)))


def ref_diversity(x: np.ndarray, rng: np.random.Generator) -> float:
    """Mean over 100 pairs (u_i, v_i) of ||x_u - x_v||, u then v drawn without replacement."""
    first = rng.choice(x.shape[0], 100, replace=False)
    second = rng.choice(x.shape[0], 100, replace=False)
    return float(sum(math.dist(x[u], x[v]) for u, v in zip(first, second)) / 100)


def reference_clip(pred: np.ndarray, gt: np.ndarray, partner: np.ndarray, seed: int) -> dict[str, float]:
    n = min(len(pred), len(gt), len(partner))
    pred, gt, partner = (np.asarray(x[:n], dtype=np.float64) for x in (pred, gt, partner))
    out = {}
    for i, (c, sl, k) in enumerate(COMPONENTS):
        p, g, a = pred[:, sl], gt[:, sl], partner[:, sl]
        out[f"fd_{c}"] = ref_frechet(p, g)
        out[f"pfd_{c}"] = ref_frechet(np.concatenate([a, g], axis=1), np.concatenate([a, p], axis=1))
        out[f"mse_{c}"] = float(np.mean((p - g) ** 2))
        out[f"sid_{c}"] = ref_sid(p, g, k)
        out[f"sid_gtfit_{c}"] = ref_sid(g, p, k)
        corr_g = np.corrcoef(g.flatten(), a.flatten())[0, 1]
        corr_p = np.corrcoef(p.flatten(), a.flatten())[0, 1]
        out[f"rpcc_{c}"] = float(abs(corr_g - corr_p))
        velocity_gap = (p[1:] - p[:-1]) - (g[1:] - g[:-1])
        out[f"sts_{c}"] = float(np.sqrt(np.sum(velocity_gap ** 2 / 0.1)))
        out[f"var_pred_{c}"] = float(np.mean(np.var(p, axis=0)))
        out[f"var_gt_{c}"] = float(np.mean(np.var(g, axis=0)))
        out[f"div_pred_{c}"] = ref_diversity(p, np.random.default_rng([seed, i]))
        out[f"div_gt_{c}"] = ref_diversity(g, np.random.default_rng([seed, i]))
    return out


def reference_score(items: list[ScoreItem], seed: int) -> list[dict[str, float]]:
    return [reference_clip(it.pred, it.gt, it.partner, derive_seed(seed, it.stem)) for it in items]


# --- the run -----------------------------------------------------------------------------------------


def _max_abs_diff(rows_a: list[dict], rows_b: list[dict]) -> dict[str, float]:
    return {k: max(abs(a[k] - b[k]) for a, b in zip(rows_a, rows_b)) for k in KEYS}


@click.command()
@click.option("--agents", default=1066, show_default=True, help="Predicted agents (DualTalk test: 1066).")
@click.option("--reference-agents", default=100, show_default=True,
              help="Agents scored by the straightforward reference (its first N; it is slow).")
@click.option("--seed", default=0, show_default=True, help="Seed of the generated set and of the scorer.")
@click.option("--out", default=RESULTS / "score_dualtalk", show_default=True, type=click.Path(path_type=Path),
              help="Result to write (.json and .md).")
def main(agents: int, reference_agents: int, seed: int, out: Path) -> None:
    """Print clips/s of the reference and of dyadbench --jobs 1/2, speed-ups and metric differences."""
    say = (transcript := Transcript()).say

    items = make_set(agents, seed)
    ref_items = items[:reference_agents]
    frames = np.mean([it.pred.shape[0] for it in items])
    say(f"# DualTalk-suite scoring: {agents} agents, mean {frames:.0f} frames; {os.cpu_count()} CPUs; "
        f"load average before: {os.getloadavg()[0]:.2f}; python {platform.python_version()}")

    ref_rows, t_ref, cpu_ref = timed(lambda: reference_score(ref_items, seed))
    with threadpool_limits(limits=1):
        ref_rows_1, t_ref_1, cpu_ref_1 = timed(lambda: reference_score(ref_items, seed))
    report_1, t_jobs1, cpu_jobs1 = timed(lambda: score_arrays(items, jobs=1, seed=seed))
    report_2, t_jobs2, cpu_jobs2 = timed(lambda: score_arrays(items, jobs=2, seed=seed))
    say(f"# load average after: {os.getloadavg()[0]:.2f}")

    base = len(ref_items) / t_ref
    rows = [("reference, default threads", len(ref_items), t_ref, cpu_ref),
            ("reference, 1 BLAS/OpenMP thread", len(ref_items), t_ref_1, cpu_ref_1),
            ("dyadbench score_arrays --jobs 1", agents, t_jobs1, cpu_jobs1),
            ("dyadbench score_arrays --jobs 2", agents, t_jobs2, cpu_jobs2)]
    say("\n| implementation | agents | seconds | clips/s | vs reference | CPU ms/clip |\n"
        "|---|---:|---:|---:|---:|---:|")
    for name, n, seconds, cpu in rows:
        say(f"| {name} | {n} | {seconds:.1f} | {n / seconds:.1f} | {n / seconds / base:.2f}x | "
            f"{1e3 * cpu / n:.0f} |")
    say(f"\nfull set ({agents} agents) with --jobs 2: {t_jobs2:.1f} s; --jobs 2 / --jobs 1 = "
        f"{t_jobs1 / t_jobs2:.2f}x")

    product = report_1.per_item[:len(ref_items)]
    vs_ref = _max_abs_diff(product, ref_rows)
    vs_ref_1 = _max_abs_diff(product, ref_rows_1)
    vs_jobs = _max_abs_diff(report_1.per_item, report_2.per_item)
    say("\n| metric | max abs diff vs reference | vs reference 1-thread | jobs 1 vs jobs 2 |\n|---|---:|---:|---:|")
    for key in KEYS:
        say(f"| {key} | {vs_ref[key]:.3g} | {vs_ref_1[key]:.3g} | {vs_jobs[key]:.3g} |")
    worst = max(max(vs_ref.values()), max(vs_ref_1.values()), max(vs_jobs.values()))
    say(f"\nlargest difference of any metric: {worst:.3g}")
    print("wrote", *write_result(out, transcript.text(), seed=seed))


if __name__ == "__main__":
    main()
