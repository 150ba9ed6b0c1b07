"""Write synthetic splits in the DualTalk layout, byte-for-byte deterministic for a seed.

``write_dualtalk_split(out, split="test", clips=None, seed=0, jobs=1)`` writes ``out/<split>/``:

- ``<clip>_speaker{1,2}.wav``: 16 kHz mono 16-bit PCM (the generator's audio is on that grid, so it
  reads back exactly);
- ``<clip>_speaker{1,2}.npz``: ``exp`` (T,50) and ``pose`` (T,6) = [head rotation | jaw] in DualTalk's
  own order (float32, via :func:`dyadbench.datasets.dualtalk_files.write_gt_npz`), plus ``shape`` (T,100),
  ``tex`` (T,50), ``cam`` (T,3), ``light`` (T,9,3) like the release: a per-person constant plus small
  per-frame tracker jitter (the benchmark ignores them);
- ``synthetic.json``: generator name, version, source digest, seed, split and per clip the identities, turns and speech
  segments (what the DualTalk files cannot hold). Written last: its presence marks a complete split.

Clip ``i`` depends only on (seed, split, i), so the files do not depend on ``jobs``.
"""

from __future__ import annotations

import hashlib
from functools import lru_cache
from pathlib import Path

import numpy as np

from dyadbench import atomic
from dyadbench.datasets.base import DyadicClip
from dyadbench.datasets.dualtalk_files import write_gt_npz
from dyadbench.datasets.wav import write_wav
from dyadbench.motion import FPS
from dyadbench.seeding import rng as seeded_rng
from dyadbench.synth.corpus import make_clip
from dyadbench.synth.generation import SUMMARY, clip_count, map_tasks, split_folder
from dyadbench.synth.styles import GENERATOR_VERSION, split_pool

MARKER = SUMMARY
# default sizes: DualTalk's test and ood splits; train sized to generate in about a minute
SPLIT_SIZES = {"train": 800, "test": 533, "ood": 377, "val": 100}


# the modules whose code determines the written bytes (their digest is recorded in synthetic.json)
GENERATOR_MODULES = ("synth/signals.py", "synth/styles.py", "synth/timeline.py", "synth/speech.py",
                     "synth/behaviour.py", "synth/corpus.py", "synth/writers.py", "datasets/wav.py",
                     "datasets/dualtalk_files.py", "features/activity.py", "motion.py", "seeding.py")


@lru_cache(maxsize=1)
def generator_digest() -> str:
    """sha256 of the generator's source files: a cached corpus made by other code is not reused."""
    root = Path(__file__).resolve().parents[1]
    h = hashlib.sha256()
    for name in GENERATOR_MODULES:
        h.update(name.encode() + b"\0" + (root / name).read_bytes())
    return h.hexdigest()


def default_size(split: str) -> int:
    split_pool(split)  # validates the name
    return SPLIT_SIZES[split]


def render_extras(identity: str, n_frames: int, seed: int) -> dict[str, np.ndarray]:
    """``shape``, ``tex``, ``cam``, ``light`` arrays like the release: per-person constants + jitter."""
    person = seeded_rng(seed, "render-person", identity)
    frame = seeded_rng(seed, "render-frames", identity, n_frames)
    base = {"shape": person.normal(0.0, 0.8, (1, 100)), "tex": person.normal(0.0, 1.0, (1, 50)),
            "cam": np.array([[person.uniform(7.5, 9.5), person.normal(0, 0.03), person.normal(0.03, 0.02)]]),
            "light": person.normal(0.0, 0.3, (1, 9, 3)) + np.array([3.4, 0, 0, 0, 0, 0, 0, 0, 0])[None, :, None]}
    jitter = {"shape": 0.1, "tex": 0.08, "cam": 0.01, "light": 0.05}
    return {k: v.astype(np.float32) + np.float32(jitter[k]) * frame.standard_normal(
        (n_frames, *v.shape[1:]), dtype=np.float32) for k, v in base.items()}


def write_clip(folder: Path, clip: DyadicClip, seed: int) -> None:
    """The four DualTalk files of one synthetic dialogue."""
    for p in clip.participants:
        stem = folder / f"{clip.clip_id}_{p.name}"
        write_wav(stem.with_suffix(".wav"), p.audio, clip.sample_rate)
        write_gt_npz(stem.with_suffix(".npz"), p.motion,
                     extra=render_extras(p.identity or clip.clip_id, p.motion.shape[0], seed))


def clip_record(clip: DyadicClip) -> dict:
    """What ``synthetic.json`` keeps about one clip."""
    return {"frames": clip.num_frames,
            "identities": {p.name: p.identity for p in clip.participants},
            "turns": [[who, float(s), float(e)] for who, s, e in clip.meta["turns"]],
            "segments": {who: [[s, e, kind] for s, e, kind in segs]
                         for who, segs in clip.meta["segments"].items()},
            "events": {who: {kind: [float(t) for t in times] for kind, times in events.items()}
                       for who, events in clip.meta["events"].items()}}


def _write_one(args: tuple[Path, str, int, int]) -> tuple[str, dict]:
    folder, split, index, seed = args
    clip = make_clip(split, index, seed)
    write_clip(folder, clip, seed)
    return clip.clip_id, clip_record(clip)


def write_dualtalk_split(out: str | Path, *, split: str = "test", clips: int | None = None, seed: int = 0,
                         jobs: int = 1, progress: bool = True, force: bool = False) -> dict:
    """Generate ``clips`` dialogues of ``split`` (default: the split's standard size) into ``out/<split>/``.

    The split folder is replaced whole when complete (:func:`dyadbench.synth.generation.split_folder`;
    ``force``: even when it holds files the generator did not write). Returns the summary also written
    to ``out/<split>/synthetic.json``.
    """
    n = clip_count(clips, default_size(split), jobs)
    folder = Path(out) / split
    with split_folder(folder, "dualtalk", force) as staging:
        tasks = [(staging, split, i, seed) for i in range(n)]
        results = map_tasks(_write_one, tasks, jobs=jobs, desc=f"synth dualtalk/{split}", unit="clip",
                            progress=progress, chunksize=4)
        records = dict(sorted(results))
        frames = sum(r["frames"] for r in records.values())
        summary = {"layout": "dualtalk", "generator": "dyadbench.synth", "version": GENERATOR_VERSION,
                   "generator_digest": generator_digest(), "seed": seed, "split": split,
                   "style_pool": split_pool(split), "clips": n, "hours": frames / FPS / 3600.0, "records": records}
        atomic.write_json(staging / MARKER, summary)
    return {**{k: v for k, v in summary.items() if k != "records"}, "folder": str(folder)}
