"""The progressive-context streaming protocol: one turn at a time, inputs sliced by the protocol.

For turn t of a clip (turns of ``config.turn_seconds``) the model receives, for the window of the
h = min(t, n) previous turns plus the current one: the user's (partner's) motion and speech and the
agent's own speech, all ground truth; optionally (``history_agent = outputs``) its own outputs for the
h history turns; and, only for oracle models, the agent's ground-truth motion of the window. A model
with a seed window (``ModelInfo.seed_frames`` > 0, e.g. StyGazeTalk's "initial motion window") gets that
ground truth too, but only for the turns that lie entirely inside its first ``seed_frames`` frames;
scores skip those frames. Every array
handed over is a fresh read-only copy of exactly that window, so a model cannot reach frames after the
current turn (a NumPy view would expose the whole clip through ``.base``). Audio shorter than the
motion is zero-padded at the end; frames after the last whole turn are dropped (``tail = truncate``)
or filled with the last predicted frame (``tail = pad-last``).

With ``speech_norm = clip`` the stream context carries the (mean, variance) of each participant's
whole-clip waveform (:func:`clip_audio_stats`); that is the only information about later audio a model
gets, and it is why such runs are recorded as not strictly causal.

Single-participant clips (gaze–head sessions) stream with empty user arrays: ``user_motion`` has shape
(frames, 0) and ``user_audio`` shape (0,). Speech features a dataset ships (``Participant.speech_features``,
r rows per frame) are sliced over the same frames as the motion; they are ``None`` when it ships none.
"""

from __future__ import annotations

import time
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field

import numpy as np

from dyadbench.datasets.base import DyadicClip, Participant
from dyadbench.errors import ConfigError, InputError
from dyadbench.protocol.config import ProtocolConfig
from dyadbench.protocol.interface import StreamContext, StreamingModel, TurnInput
from dyadbench.seeding import derive_seed


@dataclass(frozen=True)
class StreamOutput:
    """Agent motion for one evaluated direction of one clip.

    ``motion`` (T', D) float32 with T' = num_turns · frames_per_turn (+ tail_frames with pad-last);
    ``turn_latency_s`` the wall-clock seconds of each model call (one per turn; one per clip offline).
    """

    stem: str
    motion: np.ndarray
    turn_latency_s: list[float] = field(default_factory=list)
    num_turns: int = 0
    frames_per_turn: int = 0
    tail_frames: int = 0
    protocol: str = "streaming"


def clip_audio_stats(audio: np.ndarray) -> tuple[float, float]:
    """(mean, variance) of a whole-clip waveform, in float32 as the released feature extractors compute them."""
    x = np.asarray(audio, dtype=np.float32)
    return (float(x.mean()), float(x.var())) if x.size else (0.0, 0.0)


def stream_context(clip: DyadicClip, agent: str, config: ProtocolConfig,
                   stats_clip: DyadicClip | None = None) -> StreamContext:
    """The :class:`StreamContext` of one direction; the per-stream seed is derived from (seed, clip, agent).

    With ``config.speech_norm == "clip"`` it carries each participant's whole-clip waveform statistics, taken
    from ``stats_clip`` when given (the causality check keeps the unperturbed clip's), else from ``clip``."""
    agent_p = _participant(clip, agent)
    partner = clip.partner_of(agent)
    stats = {}
    if config.speech_norm == "clip":
        source = stats_clip or clip
        stats = {"agent_audio_stats": clip_audio_stats(source.participant(agent).audio),
                 "user_audio_stats": clip_audio_stats(source.partner_of(agent).audio) if partner else None}
    frames = config.frames_per_turn(clip.fps)
    return StreamContext(
        clip_id=clip.clip_id, agent=agent, user=partner.name if partner else None, fps=clip.fps,
        sample_rate=clip.sample_rate, frames_per_turn=frames,
        samples_per_turn=config.samples_per_turn(clip.sample_rate), context_turns=config.context,
        num_turns=clip.num_frames // frames, seed=derive_seed(config.seed, clip.clip_id, agent),
        agent_identity=agent_p.identity, speech_norm=config.speech_norm, **stats)


class _Direction:
    """One stream's inputs (sliced turn by turn as the module docstring says) and the outputs so far."""

    def __init__(self, model: StreamingModel, clip: DyadicClip, agent: str, config: ProtocolConfig,
                 stats_clip: DyadicClip | None = None):
        self.ctx = stream_context(clip, agent, config, stats_clip)
        self.stem = f"{clip.clip_id}_{agent}"
        if self.ctx.num_turns == 0:
            raise InputError(self.stem, f"clip has {clip.num_frames} frames, shorter than one turn "
                                        f"({self.ctx.frames_per_turn} frames); nothing to stream")
        self.clip, self.config, self.name = clip, config, model.info.name
        self.agent = clip.participant(agent)
        self.partner = clip.partner_of(agent)
        self.user_motion = self.partner.motion if self.partner else np.zeros((clip.num_frames, 0), np.float32)
        self.oracle = bool(getattr(model.info, "oracle", False))
        self.seed_frames = int(getattr(model.info, "seed_frames", 0))  # turns inside it get the GT
        self.dim = clip.motion_layout.dim
        self.outputs: list[np.ndarray] = []
        self.latencies: list[float] = []

    @property
    def next_turn(self) -> int:
        return len(self.outputs)

    @property
    def done(self) -> bool:
        return len(self.outputs) == self.ctx.num_turns

    def turn_input(self, stream: int = 0) -> TurnInput:
        """The inputs of the next turn t: the window of h = min(t, n) history turns and the current one."""
        t, F, S = self.next_turn, self.ctx.frames_per_turn, self.ctx.samples_per_turn
        h = min(t, self.config.context)
        f0, f1 = (t - h) * F, (t + 1) * F
        s0, s1 = (t - h) * S, (t + 1) * S
        agent_p, partner, outputs = self.agent, self.partner, self.outputs
        return TurnInput(
            turn=t, history_turns=h, frames_per_turn=F, samples_per_turn=S,
            user_motion=readonly_window(self.user_motion, f0, f1),
            user_audio=readonly_window(partner.audio, s0, s1) if partner else np.zeros(0, np.float32),
            agent_audio=readonly_window(agent_p.audio, s0, s1),
            agent_history=(make_readonly(np.concatenate(outputs[t - h:t], axis=0) if h else
                                         np.zeros((0, self.dim), np.float32))
                           if self.config.history_agent == "outputs" else None),
            agent_motion_oracle=readonly_window(agent_p.motion, f0, f1) if self.oracle or f1 <= self.seed_frames
            else None,
            user_speech_features=feature_window(partner, f0, f1) if partner else None,
            agent_speech_features=feature_window(agent_p, f0, f1),
            stream=stream,
        )

    def add(self, out: object, latency_s: float) -> None:
        self.latencies.append(latency_s)
        self.outputs.append(check_output(out, (self.ctx.frames_per_turn, self.dim),
                                         f"{self.name} on {self.stem}, turn {self.next_turn}"))

    def result(self) -> StreamOutput:
        motion = np.concatenate(self.outputs, axis=0)
        tail = self.clip.num_frames - motion.shape[0] if self.config.tail == "pad-last" else 0
        if tail:
            motion = np.concatenate([motion, np.repeat(motion[-1:], tail, axis=0)], axis=0)
        return StreamOutput(stem=self.stem, motion=motion, turn_latency_s=self.latencies,
                            num_turns=self.ctx.num_turns, frames_per_turn=self.ctx.frames_per_turn, tail_frames=tail)


def stream_agent(model: StreamingModel, clip: DyadicClip, agent: str, config: ProtocolConfig,
                 stats_clip: DyadicClip | None = None) -> StreamOutput:
    """Run ``model`` over one direction of ``clip`` (``agent`` generated, its partner the user), one
    ``predict_turn`` call per turn; ``stats_clip``: see :func:`stream_context`."""
    direction = _Direction(model, clip, agent, config, stats_clip)
    model.start_stream(direction.ctx)
    while not direction.done:
        turn = direction.turn_input()
        start = time.perf_counter()
        out = model.predict_turn(turn)
        direction.add(out, time.perf_counter() - start)
    return direction.result()


def stream_agents(model: StreamingModel, directions: Iterable[tuple], config: ProtocolConfig,
                  batch: int) -> Iterator[StreamOutput]:
    """Stream many directions together, yielding their outputs in the order given.

    ``directions``: (clip, agent) or (clip, agent, stats_clip) tuples (``stats_clip``: see
    :func:`stream_context`).
    Up to ``batch`` streams are open at once, each in its own slot: every step hands the next turn of each
    open stream to one :meth:`~dyadbench.protocol.interface.StreamingModel.predict_turns` call; a stream that
    has had its last turn hands its slot to the next direction (read from ``directions`` only then, so a
    split is never held whole). Each turn's inputs are exactly those :func:`stream_agent` gives, and a
    model keeps its state and random draws per stream, so the outputs equal :func:`stream_agent`'s (bit for
    bit for models whose arithmetic does not depend on the batch). A turn's latency is the call's wall-clock
    time divided by the turns it held.
    """
    if batch < 1:
        raise ConfigError(f"batch must be >= 1, got {batch}")
    pending = iter(enumerate(directions))
    slots: dict[int, tuple[int, _Direction]] = {}
    finished: dict[int, StreamOutput] = {}
    emitted = 0

    def fill(free: list[int]) -> None:
        started = {}
        for slot in free:
            item = next(pending, None)
            if item is None:
                break
            index, (clip, agent, *stats) = item
            slots[slot] = (index, _Direction(model, clip, agent, config, *stats))
            started[slot] = slots[slot][1].ctx
        if started:
            model.start_streams(started)

    fill(list(range(batch)))
    while slots:
        order = sorted(slots)
        turns = [slots[slot][1].turn_input(stream=slot) for slot in order]
        start = time.perf_counter()
        outs = list(model.predict_turns(turns))
        share = (time.perf_counter() - start) / len(turns)
        if len(outs) != len(turns):
            raise InputError(model.info.name, f"predict_turns returned {len(outs)} outputs for {len(turns)} turns")
        free = []
        for slot, out in zip(order, outs):
            index, direction = slots[slot]
            direction.add(out, share)
            if direction.done:
                finished[index] = direction.result()
                del slots[slot]
                free.append(slot)
        fill(free)
        while emitted in finished:
            yield finished.pop(emitted)
            emitted += 1


def check_output(out: object, shape: tuple[int, int], source: str) -> np.ndarray:
    """A model's output as float32 of exactly ``shape`` with finite values, else an InputError."""
    arr = np.asarray(out)
    if arr.shape != shape:
        raise InputError(source, f"model returned shape {arr.shape}, expected {shape}")
    if not np.issubdtype(arr.dtype, np.number):
        raise InputError(source, f"model returned non-numeric dtype {arr.dtype}")
    arr = arr.astype(np.float32)
    if not np.isfinite(arr).all():
        raise InputError(source, "model returned non-finite values (NaN or inf)")
    return arr


def _participant(clip: DyadicClip, name: str) -> Participant:
    try:
        return clip.participant(name)
    except KeyError:
        names = ", ".join(p.name for p in clip.participants)
        raise InputError(clip.clip_id, f"no participant {name!r} (has {names})") from None


def readonly_window(array: np.ndarray, start: int, stop: int) -> np.ndarray:
    """A read-only float32 copy of rows [start, stop), zero-padded past the end of ``array``."""
    part = np.array(array[start:stop], dtype=np.float32)
    missing = (stop - start) - part.shape[0]
    if missing > 0:
        part = np.concatenate([part, np.zeros((missing,) + part.shape[1:], np.float32)], axis=0)
    return make_readonly(part)


def feature_window(person: Participant, start: int, stop: int) -> np.ndarray | None:
    """Read-only copy of ``person``'s speech-feature rows of frames [start, stop) (None without features)."""
    r = person.feature_rows_per_frame
    return None if r is None else readonly_window(person.speech_features, start * r, stop * r)


def make_readonly(array: np.ndarray) -> np.ndarray:
    array.setflags(write=False)
    return array
