"""Write synthetic splits of the embedded corpus in the REACT layout (see :mod:`dyadbench.datasets.react`).

``write_react_split(out, split="val", clips=None, seed=0, jobs=1)`` generates ``clips`` dialogues of
751 frames (30.04 s at 25 fps) with :func:`dyadbench.synth.corpus.make_clip` and writes, for each
participant ``speaker1`` / ``speaker2`` with relative path ``Synth/<clip>/<participant>/1``:

- ``<split>/Emotion/<rel>.csv``: the 25 emotion features derived from the FLAME motion by the fixed
  mapping :func:`emotion_features` (header line + 751 rows, values printed to float32 round trip);
- ``<split>/3D_FV_files/<rel>.npy``: (1, 751, 58) float32 = [exp 50, 0, 0 | head rotation 3 | 0 0 0];
- ``<split>.csv``: ``,speaker_path,listener_path`` with speaker1 as speaker and speaker2 as listener;
- for val/test, ``neighbour_emotion_<split>.npy`` (2M, 2M) in the mirrored order (:func:`neighbour_matrix`);
- ``<split>/synthetic.json``: generator, seed and the mapping's parameters (written last in the split
  folder, which is built aside and swapped in whole; ``<split>.csv`` and the neighbour matrix follow).

Audio and video are not written (the feature-level metrics do not use them). Clip ``i`` depends only on
(seed, split, i), so the files do not depend on ``jobs``.
"""

from __future__ import annotations

import io
import math
from pathlib import Path

import numpy as np

from dyadbench import atomic
from dyadbench.datasets.react import (CLIP_FRAMES, EMOTION_COLUMNS, EMOTION_DIR, FPS, FV_DIR, SCORED_SPLITS,
                                      SPLITS, mirrored, neighbour_path)
from dyadbench.errors import ConfigError
from dyadbench.motion import EXP, JAW, POSE
from dyadbench.seeding import rng as seeded_rng
from dyadbench.synth.corpus import make_clip
from dyadbench.synth.generation import SUMMARY, clip_count, map_tasks, split_folder
from dyadbench.synth.styles import GENERATOR_VERSION

MARKER = SUMMARY
SPLIT_SIZES = {"train": 200, "val": 838, "test": 838}
# emotion mapping parameters (recorded in synthetic.json)
AU_THRESHOLD = 0.4          # AU a is on when exp[:, a] exceeds its clip mean by this much
VALENCE_GAIN = 1.5          # valence = tanh(gain * centred exp . v), v a fixed unit vector
AROUSAL_JAW_GAIN = 6.0      # arousal = tanh(jaw_gain * (jaw opening - clip mean) + speed_gain * head speed) ...
AROUSAL_SPEED_GAIN = 2.0    # ... with head speed in rad/s
EXPRESSION_TEMPERATURE = 0.5
BASIS_SEED = "react-emotion-basis"
NEIGHBOUR_FRACTION = 0.03   # each sample's appropriate reactions: the nearest 3% of listener reactions ...
MIN_NEIGHBOURS = 3          # ... but at least 3 (or all N when N < 3)


def _basis() -> tuple[np.ndarray, np.ndarray]:
    """Fixed (seed-independent) valence direction (50,) and expression logit matrix (50, 8)."""
    r = seeded_rng(BASIS_SEED, GENERATOR_VERSION)
    v = r.standard_normal(50)
    return v / np.linalg.norm(v), r.standard_normal((50, 8)) / math.sqrt(50)


def emotion_features(motion: np.ndarray, fps: float = FPS) -> np.ndarray:
    """(T, 25) float32 REACT features of a (T, 56) flame56 motion, by a fixed documented mapping.

    With ``e = exp - mean_t(exp)`` (the person's clip-centred expression):
    AU_a = 1[e_a > 0.4] for a = 0..14; valence = tanh(1.5 e.v); arousal =
    tanh(6 (jaw_0 - mean jaw_0) + 2 |d rot / dt|); expression probabilities = softmax(e W / 0.5),
    with v (unit) and W (50 x 8) fixed pseudo-random matrices.
    """
    m = np.asarray(motion, dtype=np.float64)
    e = m[:, EXP] - m[:, EXP].mean(axis=0)
    v, w = _basis()
    aus = (e[:, :15] > AU_THRESHOLD).astype(np.float64)
    valence = np.tanh(VALENCE_GAIN * (e @ v))
    rot = m[:, POSE]
    speed = np.concatenate([[0.0], np.linalg.norm(np.diff(rot, axis=0), axis=1) * fps])
    jaw = m[:, JAW][:, 0]
    arousal = np.tanh(AROUSAL_JAW_GAIN * (jaw - jaw.mean()) + AROUSAL_SPEED_GAIN * speed)
    logits = (e @ w) / EXPRESSION_TEMPERATURE
    logits -= logits.max(axis=1, keepdims=True)
    probs = np.exp(logits)
    probs /= probs.sum(axis=1, keepdims=True)
    return np.concatenate([aus, valence[:, None], arousal[:, None], probs], axis=1).astype(np.float32)


def fv_coefficients(motion: np.ndarray) -> np.ndarray:
    """(1, T, 58) float32: 52 expression slots (FLAME exp 50 + two zeros), head rotation 3, translation 0."""
    m = np.asarray(motion, dtype=np.float32)
    t = len(m)
    return np.concatenate([m[:, EXP], np.zeros((t, 2), np.float32), m[:, POSE], np.zeros((t, 3), np.float32)],
                          axis=1)[None]


def neighbour_matrix(listener: np.ndarray, fraction: float = NEIGHBOUR_FRACTION) -> np.ndarray:
    """(N, N) 0/1: S[k, j] = 1 for the max(3, ceil(fraction * N)) (at most N) reactions j nearest to k.

    Reactions are compared by the Euclidean distance of their per-feature mean and standard deviation
    over time; k itself (distance 0) is always included, so every row has at least one neighbour.
    Ties are broken by index.
    """
    summary = np.concatenate([listener.mean(axis=1), listener.std(axis=1)], axis=1).astype(np.float64)
    dist = np.sqrt(((summary[:, None, :] - summary[None, :, :]) ** 2).sum(axis=2))
    np.fill_diagonal(dist, -1.0)
    n = len(listener)
    count = min(n, max(MIN_NEIGHBOURS, math.ceil(fraction * n)))
    nearest = np.argsort(dist, axis=1, kind="stable")[:, :count]
    matrix = np.zeros((n, n), dtype=np.int64)
    np.put_along_axis(matrix, nearest, 1, axis=1)
    return matrix


def _csv_text(features: np.ndarray) -> str:
    buf = io.StringIO()
    buf.write(",".join(EMOTION_COLUMNS) + "\n")
    np.savetxt(buf, features, delimiter=",", fmt="%.9g")
    return buf.getvalue()


def rel_path(clip_id: str, participant: str) -> str:
    return f"Synth/{clip_id}/{participant}/1"


def _write_one(args: tuple[Path, str, int, int]) -> tuple[tuple[str, str], list[np.ndarray]]:
    folder, split, index, seed = args
    clip = make_clip(split, index, seed, duration_s=CLIP_FRAMES / FPS)
    rels, feats = [], []
    for p in clip.participants:
        rel = rel_path(clip.clip_id, p.name)
        features = emotion_features(p.motion, clip.fps)
        atomic.write_text(folder / EMOTION_DIR / f"{rel}.csv", _csv_text(features))
        atomic.save_npy(folder / FV_DIR / f"{rel}.npy", fv_coefficients(p.motion))
        rels.append(rel)
        feats.append(features)
    return (rels[0], rels[1]), feats


def write_react_split(out: str | Path, *, split: str = "val", clips: int | None = None, seed: int = 0,
                      jobs: int = 1, progress: bool = True, force: bool = False) -> dict:
    """Generate ``clips`` dialogues (default: the split's standard size) into the REACT root ``out``.

    ``out/<split>/`` is replaced whole when complete (:func:`dyadbench.synth.generation.split_folder`;
    ``force``: even when it holds files the generator did not write); ``<split>.csv`` and the neighbour
    matrix beside it are then rewritten.
    """
    if split not in SPLITS:
        raise ConfigError(f"REACT splits are {', '.join(SPLITS)}, got {split!r}")
    n = clip_count(clips, SPLIT_SIZES[split], jobs)
    root = Path(out)
    with split_folder(root / split, "react", force) as staging:
        results = map_tasks(_write_one, [(staging, split, i, seed) for i in range(n)], jobs=jobs,
                            desc=f"synth react/{split}", progress=progress)
        pairs = [pair for pair, _ in results]
        summary = {"layout": "react", "generator": "dyadbench.synth", "version": GENERATOR_VERSION, "seed": seed,
                   "split": split, "dialogues": n, "samples": 2 * n, "frames": CLIP_FRAMES, "fps": FPS,
                   "emotion_mapping": {"au_threshold": AU_THRESHOLD, "valence_gain": VALENCE_GAIN,
                                       "arousal_jaw_gain": AROUSAL_JAW_GAIN, "arousal_speed_gain": AROUSAL_SPEED_GAIN,
                                       "expression_temperature": EXPRESSION_TEMPERATURE, "basis_seed": BASIS_SEED},
                   "audio": "not written", "video": "not written"}
        matrix = None
        if split in SCORED_SPLITS:
            person = {rel: feats[w] for pair, feats in results for w, rel in enumerate(pair)}
            listener = np.stack([person[lst] for _, lst in mirrored(pairs)])
            matrix = neighbour_matrix(listener)
            summary["neighbours"] = {"fraction": NEIGHBOUR_FRACTION, "minimum": MIN_NEIGHBOURS,
                                     "per_row": int(matrix.sum(axis=1)[0]),
                                     "rule": "nearest listener reactions by per-feature mean and std over time"}
        atomic.write_json(staging / MARKER, summary)
    lines = [",speaker_path,listener_path"] + [f"{i},{s},{lst}" for i, (s, lst) in enumerate(pairs)]
    atomic.write_text(root / f"{split}.csv", "\n".join(lines) + "\n")
    if matrix is not None:
        atomic.save_npy(neighbour_path(root, split), matrix)
    return {**summary, "folder": str(root)}
