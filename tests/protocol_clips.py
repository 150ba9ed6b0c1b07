"""Small hand-made clips for the protocol, baseline and eval tests (no corpus needed)."""

from __future__ import annotations

import numpy as np
import pytest

from dyadbench.datasets.base import DyadicClip, InMemorySource, Participant
from dyadbench.motion import LAYOUTS


def make_clip(clip_id: str, seconds: float = 4.4, *, participants: int = 2, layout: str = "flame56",
              seed: int = 0, fps: float = 25.0, sample_rate: int = 16_000) -> DyadicClip:
    """Smooth random-walk motion and noise speech; ``seconds`` need not be a whole number of turns."""
    r = np.random.default_rng(seed)
    frames = int(round(seconds * fps))
    samples = int(round(seconds * sample_rate))
    dim = LAYOUTS[layout].dim
    people = []
    for k in range(participants):
        motion = np.cumsum(r.standard_normal((frames, dim)) * 0.05, axis=0) + r.standard_normal(dim)
        audio = r.standard_normal(samples) * 0.1
        people.append(Participant(f"speaker{k + 1}", motion.astype(np.float32), audio.astype(np.float32),
                                  identity=f"id{seed}_{k}"))
    return DyadicClip(clip_id, tuple(people), fps=fps, sample_rate=sample_rate, layout=layout)


def make_source(n: int, *, split: str = "test", seed: int = 0, seconds: float = 4.4, **kwargs) -> InMemorySource:
    clips = [make_clip(f"c{i:03d}", seconds, seed=seed * 1000 + i, **kwargs) for i in range(n)]
    return InMemorySource(clips, dataset="handmade", split=split)


@pytest.fixture(autouse=True)
def isolated_cache(tmp_path_factory, monkeypatch):
    """Baseline fits go to a per-session temporary cache, never the user's cache."""
    monkeypatch.setenv("DYADBENCH_CACHE", str(tmp_path_factory.getbasetemp() / "dyadbench-cache"))
