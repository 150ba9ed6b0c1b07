"""Write synthetic splits of the embedded corpus in the Seamless Interaction layout (:mod:`dyadbench.datasets.seamless`).

``write_seamless_split(out, split="test", clips=None, seed=0, jobs=1)`` writes ``clips`` dyads into
``out/<label>/<split>/`` (label ``improvised``; ``dev`` draws from the embedded corpus's ``val`` pool).
Dyad ``i`` is clip ``i`` of :func:`dyadbench.synth.corpus.make_clip` (``duration_s`` each, default 8 s),
resampled from 25 to 30 Hz (linear interpolation) and mapped to the corpus's features by fixed rules:

- ``movement:expression`` (128) = centred FLAME expression (50) x a fixed matrix (50 x 128, entries
  N(0, 1/50)); ``movement:alignment_head_rotation`` = FLAME head rotation (rad);
  ``movement:gaze_encodings`` = 0.6 x head pitch and yaw;
- ``movement:FAUValue`` (24) = max(centred expression dims 0-23, 0); valence, arousal and the 8 emotion
  scores = :func:`dyadbench.synth.react_writer.emotion_features` (REACT's mapping) at 30 Hz;
- speech: the clip's 16 kHz speech upsampled to 48 kHz (``resample_poly(x, 3, 1)``), 16-bit mono WAV;
- SMPL-H and keypoint arrays of the spec's shapes (zeros, ``smplh:translation`` = 1e4 sentinels on
  frames 0-4, ``is_valid`` flags all true).

What the corpus does to real files is simulated, by dyad index ``i`` and seeded draws:

- invalid movement: each 60-frame block is invalid with probability 0.15 (``seeded_rng(seed, split, i,
  "blocks", participant)``); its frame-aligned movement arrays are zero, ``movement:is_valid`` (N, 1)
  float32 is 0;
- ``i % 10 == 7``: the second participant's bundle is empty (N = 0, header-only WAV);
- ``i % 10 == 8``: the dyad comes from vendor ``V01``, whose files have no movement keys;
- ``i % 10 == 9``: the dyad is written in the per-modality layout (``audio/<stem>.wav``,
  ``<group>/<name>/<stem>.npy``); the others as ``<4 digits>/<4 digits>/<stem>.{npz,wav}``.

So a split of n dyads has about 0.8 n usable dyads. ``synthetic.json`` in the split folder (written last;
the folder is built aside and swapped in whole) records the seed, the rules and the counts.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from scipy.signal import resample_poly

from dyadbench import atomic
from dyadbench.datasets.seamless import BLOCK_FRAMES, EXPRESSION, FPS, GAZE, HEAD
from dyadbench.datasets.seamless_audio import DOWN, SOURCE_RATE
from dyadbench.datasets.seamless_files import LABELS, MODALITY_AUDIO, SPLITS
from dyadbench.datasets.wav import write_wav
from dyadbench.errors import ConfigError
from dyadbench.motion import EXP, POSE
from dyadbench.seeding import rng as seeded_rng
from dyadbench.synth.corpus import make_clip
from dyadbench.synth.generation import SUMMARY, clip_count, map_tasks, split_folder
from dyadbench.synth.react_writer import emotion_features
from dyadbench.synth.styles import GENERATOR_VERSION

DEFAULT_DYADS = 40
DURATION_S = 8.0
INVALID_BLOCK_PROBABILITY = 0.15
EMPTY, NO_MOVEMENT, PER_MODALITY = 7, 8, 9  # i % 10: the simulated corpus problems
SENTINEL = 1e4
CORPUS_POOL = {"train": "train", "dev": "val", "test": "test"}
SMPLH_SHAPES = {"smplh:body_pose": (21, 3), "smplh:global_orient": (3,), "smplh:left_hand_pose": (15, 3),
                "smplh:right_hand_pose": (15, 3), "smplh:translation": (3,), "boxes_and_keypoints:box": (4,),
                "boxes_and_keypoints:keypoints": (133, 3)}
FLAGS = ("smplh:is_valid", "boxes_and_keypoints:is_valid_box")


def _expression_basis() -> np.ndarray:
    return seeded_rng("seamless-expression-basis", GENERATOR_VERSION).standard_normal((50, 128)) / math.sqrt(50)


def _to_30hz(motion: np.ndarray, fps: float) -> np.ndarray:
    n = int(round(len(motion) / fps * FPS))
    t_out, t_in = np.arange(n) / FPS, np.arange(len(motion)) / fps
    return np.stack([np.interp(t_out, t_in, motion[:, d]) for d in range(motion.shape[1])], axis=1)


def movement_features(motion: np.ndarray, fps: float, valid: np.ndarray) -> dict[str, np.ndarray]:
    """The ``movement:*`` arrays (30 Hz) of a flame56 motion at ``fps``; zero where ``valid`` is False."""
    m = _to_30hz(np.asarray(motion, np.float64), fps)
    e = m[:, EXP] - m[:, EXP].mean(axis=0)
    emotion = emotion_features(m, FPS).astype(np.float64)
    arrays = {EXPRESSION[0]: e @ _expression_basis(), HEAD[0]: m[:, POSE], GAZE[0]: 0.6 * m[:, POSE][:, :2],
              "movement:FAUValue": np.maximum(e[:, :24], 0.0), "movement:emotion_valence": emotion[:, 15:16],
              "movement:emotion_arousal": emotion[:, 16:17], "movement:emotion_scores": emotion[:, 17:25]}
    out = {k: (a * valid[:len(a), None]).astype(np.float32) for k, a in arrays.items()}
    out["movement:is_valid"] = valid[:len(m), None].astype(np.float32)
    return out


def _other_arrays(n: int) -> dict[str, np.ndarray]:
    arrays = {k: np.zeros((n,) + s, np.float32) for k, s in SMPLH_SHAPES.items()}
    arrays["smplh:translation"][:5] = SENTINEL
    arrays.update({k: np.ones(n, bool) for k in FLAGS})
    return arrays


def _stem(split: str, index: int, participant: int, vendor: int) -> str:
    """Sessions and people of different splits never share a number (split code 0/1/2 leads both)."""
    code = SPLITS.index(split)
    return f"V{vendor:02d}_S{code}{index // 100:03d}_I{index:08d}_P{code}{2 * index + participant:04d}"


def _write_bundle(folder: Path, stem: str, arrays: dict[str, np.ndarray], audio: np.ndarray, per_modality: bool) -> None:
    if per_modality:
        for key, array in arrays.items():
            group, _, name = key.partition(":")
            atomic.save_npy(folder / group / name / f"{stem}.npy", array)
        write_wav(folder / MODALITY_AUDIO / f"{stem}.wav", audio, SOURCE_RATE)
        return
    sub = folder / stem[4:8] / stem[-4:]  # numbered sub-folders like the download tools'
    atomic.save_npz(sub / f"{stem}.npz", **arrays)
    write_wav(sub / f"{stem}.wav", audio, SOURCE_RATE)


def _write_one(args: tuple[Path, str, int, int, float]) -> str:
    folder, split, index, seed, duration = args
    clip = make_clip(CORPUS_POOL[split], index, seed, duration_s=duration)
    kind = index % 10
    for k, p in enumerate(clip.participants):
        stem = _stem(split, index, k, vendor=1 if kind == NO_MOVEMENT else 0)
        n = int(round(clip.num_frames / clip.fps * FPS))
        blocks = seeded_rng(seed, split, index, "blocks", k).random(math.ceil(n / BLOCK_FRAMES))
        valid = np.repeat(blocks >= INVALID_BLOCK_PROBABILITY, BLOCK_FRAMES)[:n]
        audio = np.clip(resample_poly(np.asarray(p.audio, np.float64), DOWN, 1), -1.0, 1.0)[:int(n / FPS * SOURCE_RATE)]
        arrays = _other_arrays(n)
        if kind != NO_MOVEMENT:
            arrays.update(movement_features(p.motion, clip.fps, valid))
        if kind == EMPTY and k == 1:
            arrays = {key: a[:0] for key, a in arrays.items()}
            audio = audio[:0]
        _write_bundle(folder, stem, arrays, audio, per_modality=kind == PER_MODALITY)
    return {EMPTY: "empty", NO_MOVEMENT: "no_movement", PER_MODALITY: "per_modality"}.get(kind, "bundle")


def write_seamless_split(out: str | Path, *, split: str = "test", clips: int | None = None, seed: int = 0,
                         jobs: int = 1, progress: bool = True, force: bool = False, label: str = LABELS[0],
                         duration_s: float = DURATION_S) -> dict:
    """Generate ``clips`` dyads (default 40) of ``duration_s`` seconds into ``out/<label>/<split>/``
    (see the module docstring); returns the summary written as ``synthetic.json``."""
    if split not in SPLITS:
        raise ConfigError(f"Seamless Interaction splits are {', '.join(SPLITS)}, got {split!r}")
    if label not in LABELS:
        raise ConfigError(f"Seamless Interaction labels are {', '.join(LABELS)}, got {label!r}")
    n = clip_count(clips, DEFAULT_DYADS, jobs)
    with split_folder(Path(out) / label / split, "seamless", force) as staging:
        kinds = map_tasks(_write_one, [(staging, split, i, seed, duration_s) for i in range(n)], jobs=jobs,
                          desc=f"synth seamless/{label}/{split}", progress=progress)
        summary = {"layout": "seamless", "generator": "dyadbench.synth", "version": GENERATOR_VERSION, "seed": seed,
                   "label": label, "split": split, "dyads": n, "duration_s": duration_s, "fps": FPS,
                   "audio_rate": SOURCE_RATE, "invalid_block_probability": INVALID_BLOCK_PROBABILITY,
                   "block_frames": BLOCK_FRAMES, "kinds": {k: kinds.count(k) for k in sorted(set(kinds))},
                   "rules": "dyad i: i % 10 == 7 second bundle empty, == 8 vendor V01 without movement, "
                            "== 9 per-modality layout"}
        atomic.write_json(staging / SUMMARY, summary)
    return {**summary, "folder": str(Path(out))}
