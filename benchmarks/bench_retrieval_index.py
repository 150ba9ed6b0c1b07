"""nn-retrieval queries: the k-d tree in PCA space against brute-force scans.

The index is built (as ``baselines.retrieval`` does) from the first ``--train`` dialogues of the
synthetic train split; the queries are the partner features of every turn of both directions of the
first ``--test`` test dialogues. Three ways to find the nearest train turn:

- ``kdtree-pca``: what the baseline does (scipy cKDTree over the PCA_DIMS-dimensional projection);
- ``brute-pca``: a numpy scan over the same projection (must return the same turns);
- ``brute-full``: a numpy scan over the full standardised, block-weighted features (the naive design
  without the projection); the table reports how often its answer equals the projected one.

    python benchmarks/bench_retrieval_index.py [--train 128] [--test 40]   # writes benchmarks/results/retrieval_index.*
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from baselines.retrieval import build_index, partner_features, split_turns, turn_speech  # noqa: E402
from dyadbench.datasets.base import InMemorySource  # noqa: E402
from dyadbench.datasets.synthetic import DEFAULT_SEED  # noqa: E402
from dyadbench.synth.corpus import make_clips  # noqa: E402
from output import RESULTS, preformatted, write_result  # noqa: E402  (benchmarks/output.py)


def _queries(clips, frames: int, samples: int) -> np.ndarray:
    rows = []
    for clip in clips:
        k = clip.num_frames // frames
        for agent in clip.participants:
            user = clip.partner_of(agent.name)
            speech = turn_speech(split_turns(user.audio, k, samples), None, clip.sample_rate, clip.fps)
            rows.append(partner_features(split_turns(np.asarray(user.motion, np.float64), k, frames), speech))
    return np.concatenate(rows)


def _brute(points: np.ndarray, queries: np.ndarray) -> np.ndarray:
    sq = (points ** 2).sum(axis=1)
    return np.array([int(np.argmin(sq - 2.0 * points @ q)) for q in queries])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--train", type=int, default=128)
    parser.add_argument("--test", type=int, default=40)
    parser.add_argument("--out", type=Path, default=RESULTS / "retrieval_index",
                        help="Result to write (.json and .md).")
    args = parser.parse_args()
    train = InMemorySource(make_clips("train", args.train), "synthetic", "train")
    index = build_index(train, 1.0)
    raw = _queries(make_clips("test", args.test), 25, 16_000)
    z = (raw - index["feat_mean"]) / index["feat_std"] * index["weights"] - index["z_mean"]
    projected = z @ index["axes"].T
    # the full-feature index, rebuilt from the train features the same way
    train_raw = _queries(list(train), 25, 16_000)
    train_z = (train_raw - index["feat_mean"]) / index["feat_std"] * index["weights"] - index["z_mean"]

    timings = {}
    start = time.perf_counter()
    tree = cKDTree(index["points"])
    build_s = time.perf_counter() - start
    start = time.perf_counter()
    _, kd = tree.query(projected, k=1)
    timings["kdtree-pca"] = time.perf_counter() - start
    start = time.perf_counter()
    brute_pca = _brute(index["points"], projected)
    timings["brute-pca"] = time.perf_counter() - start
    start = time.perf_counter()
    brute_full = _brute(train_z, z)
    timings["brute-full"] = time.perf_counter() - start

    n = len(projected)
    lines = [f"index: {index['points'].shape[0]} train turns, {index['axes'].shape[0]} PCA dims of "
             f"{z.shape[1]} features; {n} query turns; tree build {build_s * 1e3:.1f} ms",
             f"{'method':<12} {'total s':>9} {'us/query':>10} {'vs kdtree':>10} {'same turn as kdtree':>20}"]
    same = {"kdtree-pca": 1.0, "brute-pca": float(np.mean(brute_pca == kd)),
            "brute-full": float(np.mean(brute_full == kd))}
    for name, seconds in timings.items():
        lines.append(f"{name:<12} {seconds:>9.3f} {seconds / n * 1e6:>10.1f} {seconds / timings['kdtree-pca']:>9.1f}x "
                     f"{same[name]:>19.1%}")
    print("\n".join(lines))
    text = preformatted("nn-retrieval queries: k-d tree in PCA space vs brute-force scans", "\n".join(lines))
    print("wrote", *write_result(args.out, text, seed=DEFAULT_SEED))


if __name__ == "__main__":
    main()
