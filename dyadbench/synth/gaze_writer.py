"""Write synthetic gaze–head sessions in the gaze–head layout (:mod:`dyadbench.datasets.gaze`).

``write_gaze_split(out, split="test", clips=None, seed=0, jobs=1)`` generates ``clips`` sessions with
:func:`dyadbench.synth.gaze.make_gaze_session` and writes ``out/<split>/<session>.npz`` + ``.wav``
(:func:`write_session`) and the index ``out/splits.csv`` (:func:`update_index`). Session ``i`` depends
only on (seed, split, i), so the files do not depend on ``jobs``.
"""

from __future__ import annotations

import csv
import io
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np
from tqdm import tqdm

from dyadbench import atomic
from dyadbench.datasets.base import DyadicClip
from dyadbench.datasets.gaze import INDEX, INDEX_COLUMNS, read_index
from dyadbench.datasets.wav import write_wav
from dyadbench.errors import ConfigError, InputError
from dyadbench.motion import FPS, GAZE7
from dyadbench.synth import gaze as generator
from dyadbench.synth.generation import split_folder


def write_session(split_dir: Path, clip: DyadicClip) -> Path:
    """Write a single-participant gaze7 clip as ``<split_dir>/<clip_id>.npz`` + ``.wav`` (atomically)."""
    if clip.layout != GAZE7.name or len(clip.participants) != 1:
        raise InputError(clip.clip_id, "the gaze-head layout stores single-participant gaze7 clips")
    p = clip.participants[0]
    extra = {}
    speaking = clip.meta.get("speaking", {}).get(p.name)
    if speaking is not None:
        extra["speaking"] = np.asarray(speaking, dtype=bool)
    npz = atomic.save_npz(Path(split_dir) / f"{clip.clip_id}.npz", motion=np.asarray(p.motion, np.float32),
                          fps=np.float64(clip.fps), speaker=np.str_(p.identity or ""), **extra)
    write_wav(Path(split_dir) / f"{clip.clip_id}.wav", p.audio, clip.sample_rate)
    return npz


def update_index(root: Path, split: str, sessions: list[tuple[str, str]]) -> Path:
    """Replace ``split``'s rows of ``<root>/splits.csv`` with ``sessions`` [(session, speaker)]; keep the rest."""
    root = Path(root)
    rows = [r for r in read_index(root) if r["split"] != split] if (root / INDEX).is_file() else []
    rows += [{"session": s, "speaker": spk, "split": split} for s, spk in sessions]
    rows.sort(key=lambda r: (r["split"], r["session"]))
    buf = io.StringIO()
    writer = csv.DictWriter(buf, fieldnames=INDEX_COLUMNS, lineterminator="\n")
    writer.writeheader()
    writer.writerows(rows)
    return atomic.write_text(root / INDEX, buf.getvalue())


def _write_one(args: tuple) -> dict:
    folder, split, index, seed, duration_s, preset = args
    clip = generator.make_gaze_session(split, index, seed, duration_s, preset)
    write_session(Path(folder), clip)
    return {"session": clip.clip_id, "speaker": clip.participants[0].identity, "split": split,
            "frames": clip.num_frames}


def write_gaze_split(out: Path, *, split: str, clips: int | None = None, seed: int = 0, jobs: int = 1,
                     duration_s: float | None = None, preset: str = "hage-like", force: bool = False) -> dict:
    """Write ``clips`` synthetic sessions of ``split`` in the gaze–head layout under ``out``.

    Files: ``out/<split>/<session>.npz`` + ``.wav`` and ``out/splits.csv`` (rows of other splits kept).
    The split folder is replaced whole when complete (:func:`dyadbench.synth.generation.split_folder`;
    ``force``: even when it holds files the generator did not write), then the index is updated.
    Returns a summary (sessions, frames, seconds, seed, preset).
    """
    out = Path(out)
    n = generator.DEFAULT_SESSIONS.get(split, 8) if clips is None else clips
    if split not in generator.SPLITS:
        raise ConfigError(f"unknown gaze split {split!r} (known: {', '.join(generator.SPLITS)})")
    with split_folder(out / split, "gaze", force) as staging:
        tasks = [(str(staging), split, i, seed, duration_s, preset) for i in range(n)]
        desc = f"gaze {split}"
        if jobs > 1 and n > 1:
            with ProcessPoolExecutor(max_workers=jobs) as pool:
                rows = list(tqdm(pool.map(_write_one, tasks), total=n, desc=desc, leave=False))
        else:
            rows = [_write_one(t) for t in tqdm(tasks, desc=desc, leave=False)]
    update_index(out, split, [(r["session"], r["speaker"]) for r in rows])
    frames = sum(r["frames"] for r in rows)
    return {"layout": "gaze", "split": split, "sessions": n, "frames": frames, "seconds": frames / FPS,
            "seed": seed, "preset": preset, "root": str(out)}
