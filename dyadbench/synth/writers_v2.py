"""Write v2 synthetic splits (:mod:`dyadbench.synth.corpus_v2`) in the DualTalk layout.

The files are v1's (:mod:`dyadbench.synth.writers`: wav + npz per speaker, ``synthetic.json`` written
last) with ``version`` 2 and v2's own source digest. v1's writer and the modules v1's digest hashes are
left byte-identical, so v1's identity (and every result recorded against it) stays current; v2's digest
is v1's digest extended by v2's own modules.
"""

from __future__ import annotations

import hashlib
from functools import lru_cache
from pathlib import Path

from dyadbench import atomic
from dyadbench.motion import FPS
from dyadbench.synth import writers
from dyadbench.synth.corpus_v2 import VERSION, make_clip
from dyadbench.synth.generation import clip_count, map_tasks, split_folder
from dyadbench.synth.styles import split_pool

#: v2's modules on top of v1's (:data:`dyadbench.synth.writers.GENERATOR_MODULES`).
V2_MODULES = ("synth/conversation.py", "synth/nodding.py", "synth/speech_v2.py", "synth/corpus_v2.py",
              "synth/writers_v2.py")


@lru_cache(maxsize=1)
def generator_digest() -> str:
    """sha256 of v1's generator digest and v2's source files."""
    root = Path(__file__).resolve().parents[1]
    h = hashlib.sha256(writers.generator_digest().encode())
    for name in V2_MODULES:
        h.update(name.encode() + b"\0" + (root / name).read_bytes())
    return h.hexdigest()


def _write_one(args: tuple[Path, str, int, int]) -> tuple[str, dict]:
    folder, split, index, seed = args
    clip = make_clip(split, index, seed)
    writers.write_clip(folder, clip, seed)
    return clip.clip_id, writers.clip_record(clip)


def write_dualtalk_split(out: str | Path, *, split: str = "test", clips: int | None = None, seed: int = 0,
                         jobs: int = 1, progress: bool = True, force: bool = False) -> dict:
    """:func:`dyadbench.synth.writers.write_dualtalk_split` for v2 clips (same arguments, files and summary)."""
    n = clip_count(clips, writers.default_size(split), jobs)
    folder = Path(out) / split
    with split_folder(folder, "dualtalk", force) as staging:
        results = map_tasks(_write_one, [(staging, split, i, seed) for i in range(n)], jobs=jobs,
                            desc=f"synth-v2 dualtalk/{split}", unit="clip", progress=progress, chunksize=4)
        records = dict(sorted(results))
        summary = {"layout": "dualtalk", "generator": "dyadbench.synth", "version": VERSION,
                   "generator_digest": generator_digest(), "seed": seed, "split": split,
                   "style_pool": split_pool(split), "clips": n,
                   "hours": sum(r["frames"] for r in records.values()) / FPS / 3600.0, "records": records}
        atomic.write_json(staging / writers.MARKER, summary)
    return {**{k: v for k, v in summary.items() if k != "records"}, "folder": str(folder)}
