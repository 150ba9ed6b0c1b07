"""I-DT fixation labelling: dyadbench's running-extrema implementation vs a naive re-computation.

The naive version follows Salvucci & Goldberg's pseudo-code literally: every time the window grows it
recomputes the dispersion over the whole window (O(window) per step), so a long fixation (a static
prediction) costs O(T²). dyadbench keeps running maxima/minima (O(1) per step). Both must give the same
labels; the table prints the time of each and the ratio.

    python benchmarks/bench_gaze_idt.py        # writes benchmarks/results/gaze_idt.{json,md}
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from dyadbench.metrics.fixations import FIXATION, SACCADE, idt_labels  # noqa: E402
from dyadbench.synth.gaze import make_gaze_sessions  # noqa: E402
from output import RESULTS, preformatted, write_result  # noqa: E402  (benchmarks/output.py)

SEED = 0


def naive_idt(gaze: np.ndarray, threshold: float = 3.5, min_frames: int = 3) -> np.ndarray:
    """Reference I-DT (pooled eyes, breaking sample excluded), dispersion recomputed from scratch."""
    def dispersion(s: int, e: int) -> float:
        w = gaze[s:e]
        yaw, pitch = w[:, [1, 3]], w[:, [0, 2]]
        return float(yaw.max() - yaw.min() + pitch.max() - pitch.min())

    labels = np.full(len(gaze), SACCADE, dtype=np.int8)
    s = 0
    while s + min_frames <= len(gaze):
        e = s + min_frames
        if dispersion(s, e) <= threshold:
            while e < len(gaze) and dispersion(s, e + 1) <= threshold:
                e += 1
            labels[s:e] = FIXATION
            s = e
        else:
            s += 1
    return labels


def timed(fn, *args, repeat: int = 3) -> tuple[float, np.ndarray]:
    best, out = float("inf"), None
    for _ in range(repeat):
        start = time.perf_counter()
        out = fn(*args)
        best = min(best, time.perf_counter() - start)
    return best, out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=RESULTS / "gaze_idt", help="Result to write (.json and .md).")
    args = parser.parse_args()
    sessions = make_gaze_sessions("test", 16, seed=SEED, duration_s=60)
    synthetic = np.concatenate([c.participants[0].motion[:, 3:7] for c in sessions]).astype(np.float64)
    cases = {
        "synthetic sessions (16 x 60 s)": synthetic,
        "static prediction (20k frames)": np.zeros((20_000, 4)),
        "slow drift (20k frames, 0.001 deg/frame)": np.cumsum(np.full((20_000, 4), 1e-3), axis=0),
    }
    lines = [f"{'case':44s} {'frames':>7s} {'dyadbench s':>12s} {'naive s':>9s} {'speed-up':>9s}  same labels"]
    for name, gaze in cases.items():
        fast_t, fast = timed(idt_labels, gaze)
        slow_t, slow = timed(naive_idt, gaze, repeat=1)
        lines.append(f"{name:44s} {len(gaze):7d} {fast_t:12.4f} {slow_t:9.4f} {slow_t / fast_t:8.1f}x  "
                     f"{bool(np.array_equal(fast, slow))}")
    print("\n".join(lines))
    text = preformatted("I-DT fixation labelling: running extrema vs naive re-computation", "\n".join(lines))
    print("wrote", *write_result(args.out, text, seed=SEED))


if __name__ == "__main__":
    main()
