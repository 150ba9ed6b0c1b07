"""The data model every adapter produces and every model, protocol and metric consumes.

A :class:`DyadicClip` holds both participants of a conversation (or one, for single-speaker gaze–head
sessions): motion at ``fps`` in a named :mod:`dyadbench.motion` layout, and mono speech at
``sample_rate`` (or, for datasets that ship no waveform, the dataset's own speech features, rows aligned
to the motion frames). A :class:`ClipSource` is one split of one dataset, read lazily clip by clip.
"""

from __future__ import annotations

import abc
from dataclasses import dataclass, field
from pathlib import Path
from typing import Iterator

import numpy as np

from dyadbench.errors import ConfigError, InputError
from dyadbench.motion import LAYOUTS, MotionLayout


@dataclass(frozen=True)
class Participant:
    """One person of a clip: ``motion`` (T, D) float32 in ``layout``; ``audio`` (S,) float32 mono.

    ``speech_features`` (T·r, B) float32: speech features the dataset ships in place of (or besides) a
    waveform, r whole rows per motion frame (Learning2Listen: 4 rows of a 128-bin mel spectrogram per
    frame); None when the dataset has none.
    """

    name: str  # e.g. "speaker1"; prediction files are named "<clip>_<name>"
    motion: np.ndarray
    audio: np.ndarray
    identity: str | None = None  # persistent person/style id when the dataset has one
    speech_features: np.ndarray | None = None

    @property
    def feature_rows_per_frame(self) -> int | None:
        """r: speech-feature rows per motion frame (None without speech features)."""
        if self.speech_features is None:
            return None
        return self.speech_features.shape[0] // max(self.motion.shape[0], 1)


@dataclass(frozen=True)
class DyadicClip:
    """A conversation clip: one or two participants, aligned in time from frame 0 / sample 0."""

    clip_id: str
    participants: tuple[Participant, ...]
    fps: float = 25.0
    sample_rate: int = 16_000
    layout: str = "flame56"
    meta: dict = field(default_factory=dict)
    agents: tuple[str, ...] | None = None  # participants the protocol generates (None: every participant)

    def __post_init__(self) -> None:
        if not 1 <= len(self.participants) <= 2:
            raise InputError(self.clip_id, f"a clip has 1 or 2 participants, got {len(self.participants)}")
        dim = self.motion_layout.dim
        for p in self.participants:
            if p.motion.ndim != 2 or p.motion.shape[1] != dim:
                raise InputError(f"{self.clip_id}_{p.name}",
                                 f"motion must be (T, {dim}) for layout {self.layout}, got {p.motion.shape}")
            _check_speech_features(f"{self.clip_id}_{p.name}", p)
        names = [p.name for p in self.participants]
        unknown = [a for a in self.agents or () if a not in names]
        if unknown or self.agents == ():
            raise InputError(self.clip_id, f"agents must name participants ({', '.join(names)}), got {self.agents}")

    @property
    def motion_layout(self) -> MotionLayout:
        return LAYOUTS[self.layout]

    @property
    def num_frames(self) -> int:
        """Common length: the shortest participant's motion (audio is cut to match by the protocol)."""
        return min(p.motion.shape[0] for p in self.participants)

    @property
    def duration_s(self) -> float:
        return self.num_frames / self.fps

    def participant(self, name: str) -> Participant:
        for p in self.participants:
            if p.name == name:
                return p
        raise KeyError(f"{self.clip_id} has no participant {name!r}")

    def partner_of(self, name: str) -> Participant | None:
        """The other participant, or None for a single-participant session."""
        others = [p for p in self.participants if p.name != name]
        return others[0] if others else None

    @property
    def agent_participants(self) -> tuple[Participant, ...]:
        """The participants the protocol generates, in clip order (every one unless ``agents`` says)."""
        return tuple(p for p in self.participants if self.agents is None or p.name in self.agents)

    def agent_ids(self) -> list[str]:
        """Prediction stems of every evaluated direction: ``<clip>_<participant>``."""
        return [f"{self.clip_id}_{p.name}" for p in self.agent_participants]


def _check_speech_features(source: str, p: Participant) -> None:
    """Speech features must be (T·r, B) float rows with r ≥ 1 whole rows per motion frame."""
    feats = p.speech_features
    if feats is None:
        return
    frames = p.motion.shape[0]
    if feats.ndim != 2 or feats.shape[1] == 0 or frames == 0 or feats.shape[0] % frames or feats.shape[0] < frames:
        raise InputError(source, f"speech features must be (T·r, B) with r >= 1 whole rows per motion frame "
                                 f"(T = {frames}), got {feats.shape}")
    if feats.dtype.kind != "f":
        raise InputError(source, f"speech features must be floating point, got dtype {feats.dtype}")


#: The split an adapter opens when asked for none (``open_split(root, None)``) and ``root`` is a dataset root.
DEFAULT_SPLIT = "test"


def split_folder_mismatch(folder: str | Path, name: str, split: str) -> ConfigError:
    """The error for asking a single split folder for another split than the one it is."""
    return ConfigError(f"{folder} is a single split folder ({name!r}), not a dataset root, so it has no "
                       f"{split!r} split; pass the root folder that holds {split}/ instead (or split {name!r})")


class ClipSource(abc.ABC):
    """One split of one dataset, read lazily. Subclasses implement ``clip_ids`` and ``load``.

    ``single_split`` is True when the adapter was given one split folder rather than a dataset root: the
    source is then named by that folder (``split`` is the folder's name) and no other split, train
    included, can be reached from it.
    """

    dataset: str = "unknown"
    split: str = "unknown"
    root: Path | None = None
    suite: str | None = None  # metric suite `dyadbench eval` scores this dataset with (None: the layout's)
    single_split: bool = False

    @abc.abstractmethod
    def clip_ids(self) -> list[str]:
        """Sorted clip identifiers of this split."""

    @abc.abstractmethod
    def load(self, clip_id: str) -> DyadicClip:
        """Read one clip from disk (or generate it)."""

    def __len__(self) -> int:
        return len(self.clip_ids())

    def __iter__(self) -> Iterator[DyadicClip]:
        for clip_id in self.clip_ids():
            yield self.load(clip_id)

    def participant_motions(self, clip_id: str) -> tuple[np.ndarray, ...]:
        """The motion arrays of a clip's participants in clip order (what content digests hash,
        :mod:`dyadbench.provenance`). Subclasses may read the motion files only."""
        return tuple(p.motion for p in self.load(clip_id).participants)

    def generated_by(self) -> dict | None:
        """For a generated split whose content follows from its generator: the generator's identity
        (name, version, source digest, seed, split), each clip determined by it and the clip id.
        None for recorded data."""
        return None

    def describe(self) -> dict:
        """Identification recorded in results."""
        return {"dataset": self.dataset, "split": self.split, "root": str(self.root) if self.root else None,
                "clips": len(self)}


class InMemorySource(ClipSource):
    """A split held in memory (tests, generated data, subsets of another source)."""

    def __init__(self, clips: list[DyadicClip], dataset: str = "memory", split: str = "test"):
        self._clips = {c.clip_id: c for c in clips}
        if len(self._clips) != len(clips):
            raise InputError(dataset, "duplicate clip ids")
        self.dataset, self.split = dataset, split

    def clip_ids(self) -> list[str]:
        return sorted(self._clips)

    def load(self, clip_id: str) -> DyadicClip:
        try:
            return self._clips[clip_id]
        except KeyError:
            raise InputError(f"{self.dataset}/{self.split}", f"no clip {clip_id!r}") from None
