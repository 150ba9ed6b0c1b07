"""The model interface every evaluated model implements (reference models, baselines, users' own).

Streaming models implement :class:`StreamingModel`: the protocol (:mod:`dyadbench.protocol`) calls
``start_stream`` once per evaluated direction of a clip, then ``predict_turn`` once per turn with
inputs it has sliced itself, so a model cannot read future frames. Streaming many directions at once
(``--batch``), it calls ``start_streams`` with the streams of free slots and ``predict_turns`` with the next
turn of every open stream; the defaults run one shallow copy of the model per stream, so a model that only
implements ``predict_turn`` streams in batches unchanged, and a model that batches its forward passes
overrides both. Full-sequence models implement
:class:`OfflineModel` and are run by the offline protocol (recorded as ``protocol = offline``).

Models are created by factories registered in :data:`dyadbench.registry.MODELS`; a factory takes a
:class:`ModelOptions` and returns a model instance.
"""

from __future__ import annotations

import abc
import copy
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np

from dyadbench.datasets.base import ClipSource


@dataclass(frozen=True)
class ModelInfo:
    """What a result records about a model."""

    name: str
    layout: str = "flame56"  # motion layout it produces (dyadbench.motion.LAYOUTS)
    version: str = "1"
    weights_digest: str | None = None  # sha256 of the checkpoint file (None: no weights)
    weights_path: str | None = None
    oracle: bool = False  # True only for models that read the agent's ground truth (never ranked)
    config: dict = field(default_factory=dict)
    seed_frames: int = 0  # leading ground-truth frames of the agent handed over as a seed window (scores skip them)


@dataclass(frozen=True)
class ModelOptions:
    """Everything a model factory may use. ``train_split`` opens the train split lazily (baselines); the
    command line gives a :class:`~dyadbench.protocol.train_split.TrainSplit`, refused when it holds evaluated
    clips."""

    weights: Path | None = None
    seed: int = 0
    device: str = "cpu"
    cfg_scale: float = 1.0
    train_split: Callable[[], ClipSource] | None = None
    dataset: str | None = None  # registry name of the evaluated dataset: picks shipped weights (dyadbench.shipped)
    extra: dict = field(default_factory=dict)


@dataclass(frozen=True)
class StreamContext:
    """One evaluated direction of one clip: the agent is generated, the user is its partner."""

    clip_id: str
    agent: str  # participant name of the agent, e.g. "speaker1"
    user: str | None  # partner's name; None for single-participant (gaze–head) sessions
    fps: float
    sample_rate: int
    frames_per_turn: int
    samples_per_turn: int
    context_turns: int  # n: history turns given to the model (0 = none)
    num_turns: int  # turns the protocol will request for this stream
    seed: int  # per-stream seed derived from the run seed, clip and agent
    agent_identity: str | None = None
    #: How models that normalise waveforms (wav2vec 2.0 front ends) get their statistics: "window" (causal,
    #: default: the audio handed over in each turn) or "clip" (the released TIMAR/DualTalk code: the whole
    #: clip's waveform, which reads future audio; such runs are recorded as not strictly causal).
    speech_norm: str = "window"
    #: (mean, variance) of the agent's / user's whole-clip waveform; set only when ``speech_norm == "clip"``.
    agent_audio_stats: tuple[float, float] | None = None
    user_audio_stats: tuple[float, float] | None = None


@dataclass(frozen=True)
class TurnInput:
    """Inputs for turn ``turn``: h = ``history_turns`` = min(turn, n) history turns, then the current one.

    All arrays cover the same window of (h + 1) turns, oldest first; the current turn is the last
    ``frames_per_turn`` frames / ``samples_per_turn`` samples.

    - ``user_motion`` ((h+1)·F, D_user); D_user = 0 for single-participant sessions.
    - ``user_audio`` ((h+1)·S,), empty for single-participant sessions.
    - ``agent_audio`` ((h+1)·S,).
    - ``agent_history`` (h·F, D): the model's own earlier outputs for the history turns, only when the
      run's history policy is ``outputs``; ``None`` when history agent motion is masked (default).
    - ``agent_motion_oracle`` ((h+1)·F, D): the agent's ground truth, given only to models whose
      :class:`ModelInfo` says ``oracle=True``, and for the turns that lie entirely inside a model's seed
      window (``ModelInfo.seed_frames``); ``None`` otherwise.
    - ``user_speech_features`` / ``agent_speech_features`` ((h+1)·F·r, B): the speech features the
      dataset ships for that person (r rows per frame, e.g. Learning2Listen's 4 × 128-bin mel rows),
      over the same window; ``None`` when the dataset ships none (then use the waveform).
    - ``stream``: the slot of the stream the turn belongs to in :meth:`StreamingModel.predict_turns`
      (0 in single-stream runs).
    """

    turn: int
    history_turns: int
    frames_per_turn: int
    samples_per_turn: int
    user_motion: np.ndarray
    user_audio: np.ndarray
    agent_audio: np.ndarray
    agent_history: np.ndarray | None = None
    agent_motion_oracle: np.ndarray | None = None
    user_speech_features: np.ndarray | None = None
    agent_speech_features: np.ndarray | None = None
    stream: int = 0

    @property
    def current_user_motion(self) -> np.ndarray:
        return self.user_motion[-self.frames_per_turn:]

    @property
    def current_user_audio(self) -> np.ndarray:
        return self.user_audio[-self.samples_per_turn:] if self.user_audio.size else self.user_audio

    @property
    def current_agent_audio(self) -> np.ndarray:
        return self.agent_audio[-self.samples_per_turn:]

    @property
    def current_user_speech_features(self) -> np.ndarray | None:
        """The current turn's rows of ``user_speech_features`` (None when the dataset ships none)."""
        feats = self.user_speech_features
        return None if feats is None else feats[-(feats.shape[0] // (self.history_turns + 1)):]


class StreamingModel(abc.ABC):
    """A causal model: one turn of agent motion per call."""

    info: ModelInfo

    def start_stream(self, ctx: StreamContext) -> None:
        """Reset per-stream state (caches, RNG from ``ctx.seed``). Called before the first turn."""

    @abc.abstractmethod
    def predict_turn(self, turn: TurnInput) -> np.ndarray:
        """Agent motion of the current turn, shape (frames_per_turn, D), finite floats."""

    def start_streams(self, contexts: Mapping[int, StreamContext]) -> None:
        """Start a stream in each given slot (what ``start_stream`` does for one stream); streams open in other
        slots keep their state. Default: each slot gets a shallow copy of this model (the weights shared)
        started with ``start_stream``."""
        copies = self.__dict__.setdefault("_slot_models", {})
        for slot, ctx in contexts.items():
            copies[slot] = copy.copy(self)
            copies[slot].__dict__.pop("_slot_models", None)  # a copy must not hold on to the other copies
            copies[slot].start_stream(ctx)

    def predict_turns(self, turns: Sequence[TurnInput]) -> list[np.ndarray]:
        """Agent motion of the current turn of several open streams (``turn.stream``: the slot, one turn per
        slot), in the order given; each as ``predict_turn`` would give it for that stream alone, random
        draws included (they come from each stream's own generator). Default: ``predict_turn`` of each
        slot's copy in turn."""
        copies = self.__dict__.get("_slot_models", {})
        return [copies[turn.stream].predict_turn(turn) for turn in turns]


def predict_in_groups(turns: Sequence[TurnInput], key: Callable[[int, TurnInput], object],
                      predict: Callable[[list[int]], Sequence[np.ndarray]]) -> list[np.ndarray]:
    """A batched ``predict_turns``: the turns with equal ``key(i, turn)`` form one group (groups in order of
    first appearance), ``predict(indices)`` gives the outputs of one group in the order of its indices, and
    the outputs come back in the order of ``turns``."""
    groups: dict[object, list[int]] = {}
    for i, turn in enumerate(turns):
        groups.setdefault(key(i, turn), []).append(i)
    out: list[np.ndarray | None] = [None] * len(turns)
    for members in groups.values():
        for i, x in zip(members, predict(members)):
            out[i] = x
    return out


class StatefulStreams(StreamingModel):
    """A streaming model whose per-stream state is one object per stream, batched across streams.

    Subclasses call ``super().__init__()`` and implement ``_new_stream(ctx)`` (the state of a fresh stream,
    validating ``ctx``), ``_group_key(i, turn)`` (turns that may share one batch share a key) and
    ``_run(states, turns)`` (the current turn of each given stream, in order). ``start_stream`` /
    ``predict_turn`` run one stream as a batch of one; ``start_streams`` / ``predict_turns`` keep one state per
    slot and run each group of turns through ``_run`` (:func:`predict_in_groups`).
    """

    def __init__(self) -> None:
        self._stream: object | None = None  # the stream of start_stream / predict_turn
        self._slots: dict[int, object] = {}  # the streams of start_streams / predict_turns

    @abc.abstractmethod
    def _new_stream(self, ctx: StreamContext) -> object:
        """The state of a stream starting with ``ctx`` (raises on a context the model cannot run)."""

    @abc.abstractmethod
    def _group_key(self, i: int, turn: TurnInput) -> object:
        """Key of turn ``i``: the turns of one ``_run`` call share it."""

    @abc.abstractmethod
    def _run(self, states: list, turns: list[TurnInput]) -> list[np.ndarray]:
        """Agent motion of the current turn of each stream (``states[b]`` with ``turns[b]``)."""

    def start_stream(self, ctx: StreamContext) -> None:
        self._stream = self._new_stream(ctx)

    def start_streams(self, contexts: Mapping[int, StreamContext]) -> None:
        for slot, ctx in contexts.items():
            self._slots[slot] = self._new_stream(ctx)

    def predict_turn(self, turn: TurnInput) -> np.ndarray:
        if self._stream is None:
            raise RuntimeError("predict_turn called before start_stream")
        return self._run([self._stream], [turn])[0]

    def predict_turns(self, turns: Sequence[TurnInput]) -> list[np.ndarray]:
        missing = [t.stream for t in turns if t.stream not in self._slots]
        if missing:
            raise RuntimeError(f"predict_turns called for slots {missing} before start_streams")
        return predict_in_groups(turns, self._group_key, lambda group: self._run(
            [self._slots[turns[i].stream] for i in group], [turns[i] for i in group]))


class OfflineModel(abc.ABC):
    """A full-sequence (non-causal) model, run by the offline protocol."""

    info: ModelInfo

    @abc.abstractmethod
    def predict_clip(self, ctx: StreamContext, user_motion: np.ndarray, user_audio: np.ndarray,
                     agent_audio: np.ndarray) -> np.ndarray:
        """Agent motion for the whole clip, shape (T, D) with T = len(user_motion) (or ctx frames)."""
