"""The embedded corpora: synthetic dialogues generated on first use, cached, read as DualTalk.

Two generator versions (:class:`Corpus`): dataset ``synthetic`` is v1 (:mod:`dyadbench.synth.corpus`),
dataset ``synthetic-v2`` is v2 (:mod:`dyadbench.synth.corpus_v2`: v1 plus conversational dynamics over
many seconds). The default embedded corpus is ``synthetic-v2`` (:data:`dyadbench.registry.DEFAULT_EMBEDDED`).

``open_split(None, split)`` (``open_split_v2``) uses ``<cache>/synthetic-v<generator version>/<split>/`` (the cache is
``$DYADBENCH_CACHE`` or the user's cache directory, :func:`dyadbench.paths.cache_dir`). When that folder
lacks its ``synthetic.json`` marker, or the marker names another generator version, source digest
(:func:`dyadbench.synth.writers.generator_digest`, v2: :func:`dyadbench.synth.writers_v2.generator_digest`),
seed or size, the split is (re)generated
(:mod:`dyadbench.synth`, seed ``DEFAULT_SEED``) into a temporary sibling folder which is then renamed
into place, so a split folder is never half-written. A message on stderr says when it generates and
which folder is used. A non-empty folder without the generator's marker is never replaced.
``root`` may name another folder to hold the splits (for example a shared disk).

Splits and sizes: test 533 and ood 377 dialogues (DualTalk's counts), train 800 (about 7 hours, enough
for small models, generated in about a minute), val 100; mean length about 31 s.
Clips read back carry the generator's ground truth: identities, ``meta["speaking"]`` from the generated
speech segments (``meta["speaking_source"] = "generator"``), turns, segments and the events listeners
respond to (``meta["events"][name]["phrase_end" | "emphasis"]``, seconds).
"""

from __future__ import annotations

import json
import os
import shutil
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np

from dyadbench.datasets.base import DEFAULT_SPLIT
from dyadbench.datasets.dualtalk import DualTalkSource
from dyadbench.errors import InputError
from dyadbench.features.activity import segments_mask
from dyadbench.motion import FPS
from dyadbench.paths import cache_dir
from dyadbench.synth import writers, writers_v2
from dyadbench.synth.corpus_v2 import VERSION as V2
from dyadbench.synth.generation import generated_split
from dyadbench.synth.styles import GENERATOR_VERSION
from dyadbench.synth.writers import MARKER, default_size

DEFAULT_SEED = 0


@dataclass(frozen=True)
class Corpus:
    """One generator version of the embedded corpus: its dataset name, version, source digest and writer."""

    dataset: str
    version: int
    digest: Callable[[], str]
    write: Callable[..., dict]

    def root(self) -> Path:
        """Where the corpus lives: ``<cache>/synthetic-v<version>``."""
        return cache_dir() / f"synthetic-v{self.version}"


V1 = Corpus("synthetic", GENERATOR_VERSION, writers.generator_digest, writers.write_dualtalk_split)
V2_CORPUS = Corpus("synthetic-v2", V2, writers_v2.generator_digest, writers_v2.write_dualtalk_split)


def corpus_root() -> Path:
    """Where the v1 corpus (dataset ``synthetic``) lives: ``<cache>/synthetic-v1``."""
    return V1.root()


def corpus_root_v2() -> Path:
    """Where the v2 corpus (dataset ``synthetic-v2``) lives: ``<cache>/synthetic-v2``."""
    return V2_CORPUS.root()


def _read_marker(corpus: Corpus, folder: Path, split: str) -> dict | None:
    """The split's marker when it is complete and matches the corpus's generator version, seed and size."""
    try:
        marker = json.loads((folder / MARKER).read_text())
    except (OSError, ValueError):
        return None
    expected = {"version": corpus.version, "generator_digest": corpus.digest(), "seed": DEFAULT_SEED,
                "split": split, "clips": default_size(split)}
    return marker if all(marker.get(k) == v for k, v in expected.items()) else None


def _generate(corpus: Corpus, base: Path, split: str) -> None:
    target = base / split
    stale = generated_split(target)
    if target.exists() and not stale and any(target.iterdir()):
        raise InputError(target, f"exists but holds no {MARKER} from the synthetic generator; refusing to "
                                 "overwrite it (pass an empty or new folder, or use --dataset dualtalk to read it)")
    base.mkdir(parents=True, exist_ok=True)
    jobs = max(1, min(4, os.cpu_count() or 1))
    why = "the cached copy was made by other generator code" if stale else "first use only"
    print(f"dyadbench: generating the {corpus.dataset} {split} split ({default_size(split)} dialogues, seed "
          f"{DEFAULT_SEED}) into {base / split} ({why})", file=sys.stderr)
    tmp = Path(tempfile.mkdtemp(prefix=f".{split}-", dir=base))
    try:
        corpus.write(tmp, split=split, seed=DEFAULT_SEED, jobs=jobs)
        if target.exists() and _read_marker(corpus, target, split) is None:
            shutil.rmtree(target)  # empty, or written by other generator code (checked above)
        try:
            os.rename(tmp / split, target)
        except OSError:
            if _read_marker(corpus, target, split) is None:  # not a concurrent run that finished first
                raise
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


class SyntheticSource(DualTalkSource):
    """A generated split read through the DualTalk adapter, with the generator's annotations."""

    def __init__(self, folder: Path, split: str, marker: dict, corpus: Corpus = V1):
        super().__init__(folder, split)
        self.dataset = corpus.dataset
        self._marker = marker
        self._records = marker["records"]

    def identity(self, clip_id: str, speaker: str) -> str | None:
        return self._records[clip_id]["identities"][speaker]

    def extra_meta(self, clip_id: str) -> dict:
        record = self._records[clip_id]
        n = record["frames"]
        return {"speaking": {who: segments_mask([(s, e) for s, e, _ in segs], n, FPS)
                             for who, segs in record["segments"].items()},
                "speaking_source": "generator",
                "turns": [tuple(t) for t in record["turns"]],
                "segments": {who: [tuple(s) for s in segs] for who, segs in record["segments"].items()},
                "events": {who: {kind: np.asarray(times) for kind, times in events.items()}
                           for who, events in record["events"].items()},
                "generator": {k: self._marker[k] for k in ("generator", "version", "seed", "split", "style_pool")}}

    def generated_by(self) -> dict:
        """The generator identity of the split's marker: clip ``i`` depends only on it and ``i``."""
        return {k: self._marker[k] for k in ("generator", "version", "generator_digest", "seed", "split")}

    def describe(self) -> dict:
        info = super().describe()
        info.update(generator_version=self._marker["version"], seed=DEFAULT_SEED)
        return info


def open_corpus_split(corpus: Corpus, root: Path | None, split: str | None) -> SyntheticSource:
    """A split of ``corpus`` (``split`` None: test; generated on first use into ``root`` or the cache),
    read lazily."""
    split = split or DEFAULT_SPLIT
    default_size(split)  # rejects unknown split names before anything is written
    base = corpus.root() if root is None else Path(root)
    folder = base / split
    marker = _read_marker(corpus, folder, split)
    if marker is None:
        _generate(corpus, base, split)
        marker = _read_marker(corpus, folder, split)
        if marker is None:
            raise InputError(folder, f"generation finished without a valid {MARKER}")
    print(f"dyadbench: using the {corpus.dataset} {split} split in {folder}", file=sys.stderr)
    return SyntheticSource(folder, split, marker, corpus)


def open_split(root: Path | None, split: str | None) -> SyntheticSource:
    """A split of the v1 corpus (dataset ``synthetic``), see :func:`open_corpus_split`."""
    return open_corpus_split(V1, root, split)


def open_split_v2(root: Path | None, split: str | None) -> SyntheticSource:
    """A split of the v2 corpus (dataset ``synthetic-v2``), see :func:`open_corpus_split`."""
    return open_corpus_split(V2_CORPUS, root, split)
