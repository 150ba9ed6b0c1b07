"""REACT suite: fast implementation vs the straightforward loops of the specification.

    python benchmarks/bench_react.py                 # --size small: N = 200 samples (a few minutes)
    python benchmarks/bench_react.py --size val      # N = 1676 (REACT val), R = 10, T = 750 (~15 min)

Writes benchmarks/results/react_<size>.{json,md} (``_random`` / ``_near`` appended with ``--predictions``).

Problem: R = 10 reactions of T = 750 frames per speaker sample. Ground truth: emotion features of the
embedded synthetic corpus (:func:`dyadbench.synth.react_writer.emotion_features` of generated
dialogues, tiled to N samples); neighbours: each row's nearest ``--density`` fraction of listener
reactions (the real matrix's density is not published; 2% gives ~34 neighbours per row at N = 1676).
Predictions (``--predictions``): ``plausible`` = another sample's real reaction with 10% of the AUs
flipped and noise on the continuous features; ``near`` = the same, but the reaction is one of the row's
appropriate real reactions (a model whose reactions are appropriate); ``random`` = uniform [0, 1) (the
official Random baseline).

FRDist is timed twice, side by side: today's method (``prune=False``: every candidate aligned in full
in float32, the screened ones in float64) and the pruned one (the default: early-abandoned alignments,
:mod:`dyadbench.metrics.dtw`), with a check that both give the same per-reaction values bit for bit.

Every metric of the fast implementation is timed on the full problem. The straightforward loops
(``tests/react_reference.py``: tslearn ``dtw`` per pair and group, ``np.cov`` per channel, ...) are
timed on ``--subset`` speaker rows (FRDvs: a ``--subset``-sample sub-problem) and extrapolated by the
amount of work (pairs of the subset vs the whole problem). The fast implementation is run on the same
subset and its numbers compared with the loops' (FRDist and FRSyn must be identical).
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

import react_reference as ref  # noqa: E402
from dyadbench.metrics import react  # noqa: E402
from dyadbench.synth.corpus import make_clip  # noqa: E402
from dyadbench.synth.react_writer import emotion_features, neighbour_matrix  # noqa: E402
from output import RESULTS, Transcript, preformatted, write_result  # noqa: E402  (benchmarks/output.py)

SIZES = {"small": 200, "val": 1676}
R, T = 10, 750


def build_problem(n: int, density: float, kind: str, seed: int = 0):
    clips = max(2, min(n // 2, 60))
    people = []
    for i in range(clips):
        clip = make_clip("val", i, seed, duration_s=(T + 1) / 25.0)
        people += [emotion_features(p.motion)[:T] for p in clip.participants]
    rng = np.random.default_rng(seed)
    base = np.stack(people)
    # N samples: the generated people, re-used with a random time shift so that samples differ
    listener = np.stack([np.roll(base[k % len(base)], int(rng.integers(0, T)), axis=0) for k in range(n)])
    speaker = np.stack([np.roll(base[(k + 1) % len(base)], int(rng.integers(0, T)), axis=0) for k in range(n)])
    s = neighbour_matrix(listener, density)
    if kind == "random":
        pred = rng.random((n, R, T, 25)).astype(np.float32)
    else:
        src = listener[rng.integers(0, n, size=(n, R))]
        if kind == "near":
            src = listener[np.stack([rng.choice(np.flatnonzero(s[k] == 1), size=R) for k in range(n)])]
        flip = rng.random(src[..., :15].shape) < 0.1
        pred = src.copy()
        pred[..., :15] = np.where(flip, 1.0 - src[..., :15], src[..., :15])
        pred[..., 15:] = src[..., 15:] + rng.normal(0, 0.05, src[..., 15:].shape)
    return pred.astype(np.float32), listener, speaker, s


def csr(rows_matrix):
    counts = (rows_matrix == 1).sum(axis=1)
    return np.concatenate([[0], np.cumsum(counts)]).astype(np.int64), np.nonzero(rows_matrix == 1)[1]


CPU = {}


def timed(fn, *args, **kwargs):
    """(value, wall seconds); the process CPU seconds (all threads) are kept in CPU[fn name]."""
    start, cpu = time.perf_counter(), time.process_time()
    value = fn(*args, **kwargs)
    CPU[getattr(fn, "__name__", str(fn))] = time.process_time() - cpu
    return value, time.perf_counter() - start


def timed_cpu(fn, *args, **kwargs):
    """(value, process CPU seconds): the loops run on one thread, so this is their time on an idle core."""
    value, _ = timed(fn, *args, **kwargs)
    return value, CPU[fn.__name__]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--size", choices=list(SIZES), default="small", help="small: N=200; val: N=1676")
    parser.add_argument("--n", type=int, default=None, help="number of speaker samples (overrides --size)")
    parser.add_argument("--density", type=float, default=0.02, help="neighbours per row as a fraction of N")
    parser.add_argument("--predictions", choices=["plausible", "near", "random"], default="plausible",
                        help="plausible: a perturbed real reaction of another sample; near: of an appropriate "
                             "one; random: uniform [0, 1)")
    parser.add_argument("--subset", type=int, default=2, help="speaker rows (FRDvs: samples x5) for the loops")
    parser.add_argument("--compare-screen", action="store_true",
                        help="also time FRDist without the float32 screen (every pair aligned in float64)")
    parser.add_argument("--frdist-rows", type=int, default=None,
                        help="time the fast FRDist on this many rows only and extrapolate by neighbour count "
                             "(for a full-size run on a shared machine); default: all rows")
    parser.add_argument("--out", type=Path, default=None,
                        help="Result to write (.json and .md); default benchmarks/results/react_<size>[_random]")
    args = parser.parse_args()
    say = (transcript := Transcript()).say

    n = args.n or SIZES[args.size]
    pred, listener, speaker, s = build_problem(n, args.density, args.predictions)
    warm_up()
    p, lst, sp, (indptr, indices) = react.check_inputs(pred, listener, speaker, s)
    nnz = int(s.sum())
    say(f"N={n} R={R} T={T} neighbours/row mean {nnz / n:.1f} ({args.density:.1%}), predictions={args.predictions},"
        f" cpus={os.cpu_count()}, numba threads={react_threads()}")

    fast_full, fast_cpu, outputs = {}, {}, {}
    runs = [("FRCorr", react.fr_corr, (p, lst, indptr, indices), {}),
            ("FRDist", react.fr_dist_per_reaction, (p, lst, indptr, indices), {}),
            ("FRDist (no pruning)", react.fr_dist_per_reaction, (p, lst, indptr, indices), {"prune": False}),
            ("FRDist (no screen)", react.fr_dist_per_reaction, (p, lst, indptr, indices), {"screen": False}),
            ("FRDiv", react.fr_div, (p,), {}), ("FRVar", react.fr_var, (p,), {}), ("FRDvs", react.fr_dvs, (p,), {}),
            ("FRSyn", react.fr_syn, (p, sp), {}), ("FRSyn_all", react.fr_syn, (p, sp), {"all_reactions": True})]
    dist_rows = slice(0, min(args.frdist_rows or n, n))
    dist_scale = nnz / int(s[dist_rows].sum())
    for name, fn, fn_args, fn_kwargs in runs:
        if name.endswith("(no screen)") and not args.compare_screen:
            continue
        factor = 1.0
        if name.startswith("FRDist") and dist_rows.stop < n:
            sub_ptr, sub_idx = csr(s[dist_rows])
            fn_args, factor = (p[dist_rows], lst, sub_ptr, sub_idx), dist_scale
            name = f"{name} *"
        outputs[name], seconds = timed(fn, *fn_args, **fn_kwargs)
        fast_full[name], fast_cpu[name] = seconds * factor, CPU[fn.__name__] * factor

    rows = np.sort(np.random.default_rng(1).choice(n, size=min(args.subset, n), replace=False))
    sub_s = s[rows]
    sub_nnz = int(sub_s.sum())
    sub_ptr, sub_idx = csr(sub_s)
    m = min(5 * args.subset, n)
    loops, scale, same = {}, {}, {}

    def compare(name, fast_value, slow_value, exact):
        same[name] = (fast_value == slow_value) if exact else bool(np.isclose(fast_value, slow_value, rtol=1e-12, atol=0))

    value, loops["FRCorr"] = timed_cpu(ref.fr_corr, pred[rows], listener, sub_s)
    compare("FRCorr", float(np.mean(react.fr_corr_per_reaction(p[rows], lst, sub_ptr, sub_idx).sum(axis=1))), value, False)
    scale["FRCorr"] = nnz / sub_nnz
    value, loops["FRDist"] = timed_cpu(ref.fr_dist, pred[rows], listener, sub_s)
    per = react.fr_dist_per_reaction(p[rows], lst, sub_ptr, sub_idx)
    total = np.zeros(len(rows))
    for i in range(R):
        total = total + per[:, i]
    compare("FRDist", float(np.mean(total)), value, True)
    scale["FRDist"] = nnz / sub_nnz
    for name, fn, fast_fn in (("FRDiv", ref.fr_div, react.fr_div), ("FRVar", ref.fr_var, react.fr_var)):
        value, loops[name] = timed_cpu(fn, pred[rows])
        compare(name, fast_fn(p[rows]), value, False)
        scale[name] = n / len(rows)
    value, loops["FRDvs"] = timed_cpu(ref.fr_dvs, pred[:m])
    compare("FRDvs", react.fr_dvs(p[:m]), value, False)
    scale["FRDvs"] = n * (n - 1) / (m * (m - 1))
    value, loops["FRSyn"] = timed_cpu(ref.fr_syn, pred[rows], speaker[rows])
    compare("FRSyn", react.fr_syn(p[rows], sp[rows]), value, True)
    scale["FRSyn"] = n / len(rows)
    value, loops["FRSyn_all"] = timed_cpu(ref.fr_syn, pred[rows], speaker[rows], all_reactions=True)
    compare("FRSyn_all", react.fr_syn(p[rows], sp[rows], all_reactions=True), value, True)
    scale["FRSyn_all"] = n / len(rows)

    say(f"\nloops timed on {len(rows)} speaker rows ({sub_nnz} neighbours; FRDvs on {m} samples), "
          "extrapolated to the full problem\n")
    say("fast wall = elapsed seconds; fast cpu = process CPU seconds (all threads); loops est. = CPU seconds of\n"
        "the single-threaded loops (= their time on an idle core), extrapolated\n")
    say(f"{'metric':<22}{'fast wall':>10}{'fast cpu':>10}{'loops est.':>12}{'wall x':>9}{'cpu x':>8}"
        "  identical on subset")
    total = np.zeros(3)
    for name, seconds in fast_full.items():
        key = name.split(" ")[0]
        est = loops[key] * scale[key]
        if name.rstrip(" *") == key:
            total += (seconds, fast_cpu[name], est)
        say(f"{name:<22}{seconds:>10.2f}{fast_cpu[name]:>10.2f}{est:>12.1f}{est / seconds:>8.1f}x"
            f"{est / fast_cpu[name]:>7.1f}x  {same[key]}")
    if dist_rows.stop < n:
        say(f"* fast FRDist timed on rows 0..{dist_rows.stop - 1} and extrapolated by neighbour count (x{dist_scale:.1f})")
    say(f"{'whole suite':<22}{total[0]:>10.2f}{total[1]:>10.2f}{total[2]:>12.1f}{total[2] / total[0]:>8.1f}x"
        f"{total[2] / total[1]:>7.1f}x")
    star = " *" if dist_rows.stop < n else ""
    say_side_by_side(say, loops["FRDist"] * scale["FRDist"], same["FRDist"],
                     [(label, fast_full[name + star], fast_cpu[name + star], outputs[name + star])
                      for label, name in (("today (no pruning)", "FRDist (no pruning)"), ("pruned", "FRDist"))])
    suffix = "" if args.predictions == "plausible" else f"_{args.predictions}"
    out = args.out or RESULTS / f"react_{args.size}{suffix}"
    text = preformatted("REACT suite: dyadbench vs the straightforward loops of the specification", transcript.text())
    print("wrote", *write_result(out, text, seed=0))


def say_side_by_side(say, loops_cpu: float, loops_same: bool, methods) -> None:
    """FRDist's methods in one table: the loops (estimate), then each (label, wall, cpu, per-reaction values);
    'identical' compares every method's values with the first one's, bit for bit."""
    say("\nFRDist side by side (loops: CPU seconds on one core, extrapolated; 'identical': the per-reaction "
        "values\nequal the first method's bit for bit, the loops' FRDist on the subset for the loops)\n")
    say(f"{'method':<22}{'wall s':>10}{'cpu s':>10}{'loops/wall':>12}{'loops/cpu':>11}{'vs today':>10}  identical")
    say(f"{'loops (tslearn)':<22}{loops_cpu:>10.1f}{loops_cpu:>10.1f}{1:>11.1f}x{1:>10.1f}x{'':>10}  {loops_same}")
    first = methods[0]
    for label, wall, cpu, values in methods:
        say(f"{label:<22}{wall:>10.2f}{cpu:>10.2f}{loops_cpu / wall:>11.1f}x{loops_cpu / cpu:>10.1f}x"
            f"{first[1] / wall:>9.2f}x  {np.array_equal(values, first[3])}")


def warm_up() -> None:
    """Compile / load every numba function (fast side and tslearn) before timing anything."""
    rng = np.random.default_rng(9)
    pred, listener, speaker = rng.random((3, 2, 60, 25)), rng.random((3, 60, 25)), rng.random((3, 60, 25))
    s = np.ones((3, 3), dtype=np.int64)
    react.score(pred, listener, speaker, s, reactions=None)
    ref.score(pred[:2], listener, speaker[:2], s[:2])


def react_threads() -> int:
    import numba

    return numba.get_num_threads()


if __name__ == "__main__":
    main()
