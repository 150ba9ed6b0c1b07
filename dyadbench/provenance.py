"""Content digests: which clips a split holds, independent of file names, formats and folders.

- :func:`clip_digest`: sha256 of a clip's participants' motion arrays (float32, with their shapes, in clip
  order). Speech is left out on purpose: a copy whose audio was re-encoded still holds the same motion,
  which is what a model fitted on it would reproduce.
- :func:`clip_digests`: clip id -> digest over a split. For a split on disk they are cached in
  ``<cache>/provenance/`` under a key of the split's resolved root and its files' relative paths, sizes
  and modification times (:func:`source_key`), so a repeated run reads no clip; in-memory splits are
  hashed directly.
- :func:`split_digest`: one digest of (some of) a split's clips, their ids and contents. For a generated
  split (:meth:`~dyadbench.datasets.base.ClipSource.generated_by`: the embedded corpus) it follows from the
  generator's identity and the ids, without reading a clip.
- :func:`shared_clips`: the evaluated clips whose content a train split holds too.
- :func:`root_identity`: where a split's content lives, for comparing runs.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path
from typing import Iterable

import numpy as np
from tqdm import tqdm

from dyadbench import atomic
from dyadbench.datasets.base import ClipSource
from dyadbench.paths import cache_dir

CACHE_VERSION = 1  # bump when clip_digest changes: old cache files are then never read


def source_key(source: ClipSource) -> str:
    """sha256 hex digest of a split's current files: dataset, split and the relative paths, sizes and
    modification times of every file under its root; for an in-memory split, the bytes of every clip."""
    h = hashlib.sha256(f"{source.dataset}\x1f{source.split}".encode())
    root = Path(source.root) if source.root else None
    if root is not None and root.is_dir():
        for path in sorted(p for p in root.rglob("*") if p.is_file()):
            st = path.stat()
            h.update(f"{path.relative_to(root)}\x1f{st.st_size}\x1f{st.st_mtime_ns}\n".encode())
        return h.hexdigest()
    for clip in source:
        h.update(f"{clip.clip_id}\x1f{clip.fps}\x1f{clip.sample_rate}\x1f{clip.layout}".encode())
        for p in clip.participants:
            h.update(p.name.encode())
            h.update(np.ascontiguousarray(p.motion).tobytes())
            h.update(np.ascontiguousarray(p.audio).tobytes())
    return h.hexdigest()


def clip_digest(motions: Iterable[np.ndarray]) -> str:
    """sha256 hex digest of a clip's participants' motion (each as float32 with its shape, in order)."""
    h = hashlib.sha256()
    for motion in motions:
        m = np.ascontiguousarray(motion, dtype=np.float32)
        h.update(f"{m.shape}\x1f".encode())
        h.update(m.tobytes())
    return h.hexdigest()


def _cache_file(source: ClipSource) -> Path | None:
    """Where the clip digests of a split on disk are kept (None: in memory, hashed every time)."""
    if source.root is None or not Path(source.root).is_dir():
        return None
    key = hashlib.sha256(f"{Path(source.root).resolve()}\x1f{source_key(source)}".encode()).hexdigest()
    return cache_dir() / "provenance" / f"clips-v{CACHE_VERSION}-{key[:24]}.json"


def _read_cache(path: Path | None) -> dict[str, str]:
    if path is None:
        return {}
    try:
        known = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return {}
    if not isinstance(known, dict) or not all(isinstance(v, str) for v in known.values()):
        return {}
    return known


def clip_digests(source: ClipSource, ids: Iterable[str] | None = None) -> dict[str, str]:
    """clip id -> :func:`clip_digest` for ``ids`` of ``source`` (default: every clip), cached for a split on disk."""
    ids = source.clip_ids() if ids is None else list(ids)
    path = _cache_file(source)
    known = _read_cache(path)
    missing = [c for c in ids if c not in known]
    for clip_id in tqdm(missing, desc=f"content digests of {source.dataset}/{source.split}", unit="clip",
                        leave=False, disable=len(missing) < 50):
        known[clip_id] = clip_digest(source.participant_motions(clip_id))
    if missing and path is not None:
        atomic.write_json(path, known)
    return {c: known[c] for c in ids}


def split_digest(source: ClipSource, ids: Iterable[str] | None = None) -> str:
    """sha256 hex digest of ``ids`` of ``source`` (default: every clip): their ids and contents, or for a
    generated split its generator identity and the ids."""
    ids = source.clip_ids() if ids is None else list(ids)
    generated = source.generated_by()
    h = hashlib.sha256()
    if generated is not None:
        h.update(json.dumps(generated, sort_keys=True).encode())
        for clip_id in ids:
            h.update(f"\x1e{clip_id}".encode())
    else:
        for clip_id, digest in clip_digests(source, ids).items():
            h.update(f"\x1e{clip_id}\x1f{digest}".encode())
    return h.hexdigest()


def _generator(source: ClipSource) -> dict | None:
    generated = source.generated_by()
    return None if generated is None else {k: v for k, v in generated.items() if k != "split"}


def shared_clips(train: ClipSource, evaluated: ClipSource, ids: Iterable[str]) -> list[tuple[str, str]]:
    """(evaluated id, train id) of every clip of ``ids`` whose content the train split holds too.

    Two splits of one generator are compared by id (another split shares none: clips are seeded by
    split); any other pair by :func:`clip_digests`.
    """
    ids = list(ids)
    generator = _generator(train)
    if generator is not None and generator == _generator(evaluated):
        if train.split != evaluated.split:
            return []
        known = set(train.clip_ids())
        return [(c, c) for c in ids if c in known]
    by_content = {digest: clip_id for clip_id, digest in clip_digests(train).items()}
    return [(c, by_content[d]) for c, d in clip_digests(evaluated, ids).items() if d in by_content]


def root_identity(source: ClipSource) -> str | None:
    """The resolved root folder of a split on disk; None for a generated split (its content follows from
    the generator, wherever it is cached) or an in-memory one."""
    if source.root is None or source.generated_by() is not None:
        return None
    return str(Path(source.root).resolve())
