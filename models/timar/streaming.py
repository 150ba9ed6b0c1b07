"""TIMAR under the streaming protocol: one 1-s turn per call, history agent motion always [MASK].

For turn t with n = ``context_turns``, the current turn's user speech, user motion and agent speech are
tokenised and its agent-motion slots are [MASK]; the diffusion head samples the 25 frames at once with
5 respaced ancestral steps from the stream's own seeded generator (one draw order whatever the cache
does, so cached and uncached runs give the same numbers up to float round-off).

- :class:`FaithfulStream` (``timar``): the window holds min(t, n) history turns + the current one at
  window positions 0, 1, ... (the released design). Uncached, every window is re-encoded from the
  inputs the protocol hands over. Cached, the keys/values of each turn are kept while the window still
  starts at turn 0 (t <= n), which is exact because a turn's states then never change; once the
  window slides (t > n) every turn moves to a new position, so the window is re-encoded.
- :class:`BandStream` (``timar-stream``): each turn attends to itself and the n turns before it, with
  positions inside a turn and a learned bias per turn distance, so a turn's keys/values never change
  once computed. Cached, they are computed once and reused. Uncached, the last depth·n + 1 turns (the
  receptive field of the current turn through the stacked bands) are re-encoded; that is exact too.
  The stream keeps the tokens of the turns it was given (receptive field) itself.

Classifier-free guidance (``cfg_scale`` != 1) runs a second, unconditional branch. ``guidance_null``
says what it nulls: ``"current-turn"`` (default, the release) replaces only the current turn's
user-speech and user-motion frame tokens by the null token, so history turns are the same in both
branches (their cached keys/values are the conditional branch's); ``"every-turn"`` nulls the user
frames of every turn in the window (the earlier dyadbench variant, kept as a named option).

Layouts with a validity column (``seamless``, :mod:`models.timar.layouts`): the user motion tokens are the
generated columns of the partner's motion, and a partner frame whose validity is 0 (the reader's zero-filled
blocks) becomes the null token in both branches; each predicted frame is the generated columns followed by
validity 1.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Mapping, Sequence

import numpy as np
import torch

from dyadbench.errors import ConfigError
from dyadbench.protocol.interface import ModelInfo, StreamContext, StreamingModel, TurnInput, predict_in_groups
from models.timar.backbone import KV
from models.timar.frontends import SpeechFrontend
from models.timar.layouts import timar_layout
from models.timar.model import TimarModel

GUIDANCE_NULLS = ("current-turn", "every-turn")


class _Stream:
    """One stream's state: its generator (seeded from the stream's seed), audio statistics and caches."""

    def __init__(self, ctx: StreamContext):
        self.generator = torch.Generator().manual_seed(ctx.seed)
        self.context = ctx.context_turns
        self.audio_stats = (ctx.user_audio_stats, ctx.agent_audio_stats)  # set only with speech_norm "clip"


class _TimarStreamBase(StreamingModel):
    """Per-stream state lives in :class:`_Stream` objects, one per slot (slot 0 for ``start_stream``), so
    ``predict_turns`` can run the turns of several streams in one batch: turns at the same position of their
    streams (the same window shape) share every forward pass, each stream drawing its noise from its own
    generator. ``predict_turn`` is ``predict_turns`` of one turn."""

    def __init__(self, model: TimarModel, frontend: SpeechFrontend, info: ModelInfo, *, cfg_scale: float = 1.0,
                 use_cache: bool = True, temperature: float = 1.0, clamp_variance: bool = True,
                 guidance_null: str = "current-turn", device: str = "cpu"):
        if guidance_null not in GUIDANCE_NULLS:
            raise ConfigError(f"guidance_null must be one of {', '.join(GUIDANCE_NULLS)}, got {guidance_null!r}")
        self.model = model.eval().to(device)
        self.layout = timar_layout(model.cfg.motion_dim)
        self.frontend = frontend
        self.info = info
        self.cfg_scale = float(cfg_scale)
        self.use_cache = use_cache
        self.temperature = temperature
        self.clamp_variance = clamp_variance
        self.guidance_null = guidance_null
        self.device = torch.device(device)
        self._streams: dict[int, _Stream] = {}

    def start_stream(self, ctx: StreamContext) -> None:
        self.start_streams({0: ctx})

    def start_streams(self, contexts: Mapping[int, StreamContext]) -> None:
        cfg = self.model.cfg
        for slot, ctx in contexts.items():
            if ctx.user is None:
                raise ConfigError(f"{self.info.name} needs a partner (user); {ctx.clip_id} has one participant")
            if (ctx.frames_per_turn, ctx.samples_per_turn) != (cfg.frames_per_turn, cfg.samples_per_turn):
                raise ConfigError(f"{self.info.name} was trained on turns of {cfg.frames_per_turn} frames / "
                                  f"{cfg.samples_per_turn} samples; the protocol gives {ctx.frames_per_turn} / "
                                  f"{ctx.samples_per_turn} (use --turn-seconds 1 at 25 fps, 16 kHz)")
            if ctx.context_turns > cfg.max_context:
                raise ConfigError(f"{self.info.name} supports a context of at most {cfg.max_context} history "
                                  f"turns, got {ctx.context_turns}")
            self.frontend.sample_rate, self.frontend.fps = ctx.sample_rate, ctx.fps
            self._streams[slot] = self._reset(_Stream(ctx))

    def _reset(self, stream: _Stream) -> _Stream:
        raise NotImplementedError

    def _group_key(self, turn: TurnInput, stream: _Stream) -> tuple:
        """Turns with equal keys have windows and caches of the same shape and run as one batch."""
        raise NotImplementedError

    def _predict(self, streams: list[_Stream], turns: list[TurnInput]) -> torch.Tensor:
        """Frames (streams, F, 56) of one group of turns."""
        raise NotImplementedError

    def predict_turn(self, turn: TurnInput) -> np.ndarray:
        return self.predict_turns([turn])[0]

    @torch.no_grad()
    def predict_turns(self, turns: Sequence[TurnInput]) -> list[np.ndarray]:
        def predict(members: list[int]) -> np.ndarray:
            frames = self._predict([self._streams[turns[i].stream] for i in members], [turns[i] for i in members])
            if self.layout.valid_column is not None:  # every generated frame is claimed valid
                frames = torch.cat([frames, frames.new_ones(*frames.shape[:-1], 1)], dim=-1)
            return frames.cpu().numpy().astype(np.float32)

        return predict_in_groups(turns, lambda _, turn: self._group_key(turn, self._streams[turn.stream]), predict)

    @property
    def _branches(self) -> int:
        """1 (conditional) or 2 (conditional, unconditional) when guidance is on."""
        return 1 if self.cfg_scale == 1.0 else 2

    def _tokens(self, streams: list[_Stream], windows: list[tuple[np.ndarray, np.ndarray, np.ndarray]],
                turns: int) -> torch.Tensor:
        """Tokens (streams·branches, turns, L, D) of ``turns`` whole turns of each stream's (user motion, user
        audio, agent audio), agent motion masked; rows stream-major (each stream's branches together)."""
        F, b = self.model.cfg.frames_per_turn, self._branches

        def t(xs: list[np.ndarray]) -> torch.Tensor:
            x = torch.from_numpy(np.stack([np.array(x, dtype=np.float32) for x in xs])).to(self.device)
            x = x.view(len(xs), 1, turns, F, -1).expand(-1, b, -1, -1, -1)
            return x.reshape(len(xs) * b, turns, F, x.shape[-1])

        us = [self.frontend.features(ua, turns, s.audio_stats[0]) for s, (_, ua, _) in zip(streams, windows)]
        as_ = [self.frontend.features(aa, turns, s.audio_stats[1]) for s, (_, _, aa) in zip(streams, windows)]
        um = [m[:turns * F, :self.layout.motion_dim] for m, _, _ in windows]
        user_null = torch.zeros(len(streams), b, turns, 2 * F, dtype=torch.bool, device=self.device)
        user_null[:, 1:, -1:] = True  # the unconditional branch nulls the current (last) turn's user frames ...
        if self.guidance_null == "every-turn":
            user_null[:, 1:] = True  # ... or those of every turn in the window
        if self.layout.valid_column is not None:  # invalid partner frames: null user-motion tokens
            invalid = np.stack([np.asarray(m[:turns * F, self.layout.valid_column]) <= 0.5 for m, _, _ in windows])
            user_null[..., F:] |= torch.from_numpy(invalid).to(self.device).view(len(streams), 1, turns, F)
        return self.model.turn_tokens(t(us), t(um), t(as_), user_null=user_null.flatten(0, 1))

    def _as_history(self, x: torch.Tensor) -> torch.Tensor:
        """What the current turn's tokens or keys/values (one stream's branches first) become once it is a
        history turn: with current-turn nulling the unconditional branch sees history as the conditional
        branch does."""
        return x if self.guidance_null == "every-turn" else x[:1].expand_as(x)

    def _per_stream(self, x: torch.Tensor, count: int) -> tuple[torch.Tensor, ...]:
        """Rows (streams·branches, ...) split into each stream's (branches, ...)."""
        return x.split(self._branches) if count > 1 else (x,)

    def _current_tokens(self, streams: list[_Stream], turns: list[TurnInput]) -> torch.Tensor:
        return self._tokens(streams, [(t.current_user_motion, t.current_user_audio, t.current_agent_audio)
                                      for t in turns], 1)

    def _sample(self, streams: list[_Stream], cond: torch.Tensor) -> torch.Tensor:
        """Frames (streams, F, 56) from the current turn's features (streams·branches, 1, L, D)."""
        z = cond[:, 0, self.model.agent_slice]
        if len(streams) == 1:
            x = self.model.sample_frames(z, streams[0].generator, self.cfg_scale, self.temperature,
                                         self.clamp_variance)
            return x[None]
        return self.model.sample_frames(z.unflatten(0, (len(streams), self._branches)),
                                              [s.generator for s in streams], self.cfg_scale, self.temperature,
                                              self.clamp_variance)

    @staticmethod
    def _batched_past(streams: list[_Stream], layer: int) -> list[KV]:
        """Layer ``layer``'s cached keys/values of every turn, the streams' rows joined (streams·branches, ...)."""
        if len(streams) == 1:
            return streams[0].past[layer]
        return [(torch.cat([k for k, _ in kvs]), torch.cat([v for _, v in kvs]))
                for kvs in zip(*(list(s.past[layer]) for s in streams))]


class FaithfulStream(_TimarStreamBase):
    """``timar``: window-indexed positions; exact KV cache while the window grows (t <= n)."""

    def _reset(self, stream: _Stream) -> _Stream:
        stream.past = [[] for _ in self.model.blocks]
        stream.window = deque(maxlen=stream.context)  # history turns' tokens
        return stream

    def _group_key(self, turn: TurnInput, stream: _Stream) -> tuple:
        # cached, a window that has started to slide (t > n) is re-encoded; one that has not continues the cache
        return (turn.history_turns, turn.turn > turn.history_turns)

    def _predict(self, streams: list[_Stream], turns: list[TurnInput]) -> torch.Tensor:
        count = len(streams)
        if not self.use_cache:
            turn = turns[0]
            tokens = self._tokens(streams, [(t.user_motion, t.user_audio, t.agent_audio) for t in turns],
                                  turn.history_turns + 1)
            return self._sample(streams, self.model.encode(tokens)[:, -1:])
        current = self._current_tokens(streams, turns)
        history = [torch.cat(h) if count > 1 else h[0] for h in zip(*(list(s.window) for s in streams))]
        for stream, own in zip(streams, self._per_stream(current, count)):
            stream.window.append(self._as_history(own))
        if turns[0].turn <= streams[0].context:  # window still starts at turn 0: earlier turns' states are final
            cond, kv = self.model.encode_next_turn(current, [self._batched_past(streams, layer)
                                                             for layer in range(len(self.model.blocks))])
            for layer, (k, v) in enumerate(kv):
                for stream, k_s, v_s in zip(streams, self._per_stream(k, count), self._per_stream(v, count)):
                    stream.past[layer].append((self._as_history(k_s), self._as_history(v_s)))
            return self._sample(streams, cond)
        for stream in streams:
            stream.past = [[] for _ in self.model.blocks]  # window slid: positions of every turn changed
        return self._sample(streams, self.model.encode(torch.cat([*history, current], dim=1))[:, -1:])


class BandStream(_TimarStreamBase):
    """``timar-stream``: per-turn sliding band; every turn's keys/values are computed once."""

    def _reset(self, stream: _Stream) -> _Stream:
        band = stream.context
        stream.past = [deque(maxlen=band) for _ in self.model.blocks]
        stream.turns = deque(maxlen=len(self.model.blocks) * band)  # history tokens
        return stream

    def _group_key(self, turn: TurnInput, stream: _Stream) -> tuple:
        # uncached, the re-encoded receptive field grows with t up to depth·n turns
        return (turn.history_turns, len(stream.turns))

    def _predict(self, streams: list[_Stream], turns: list[TurnInput]) -> torch.Tensor:
        count, context = len(streams), streams[0].context
        current = self._current_tokens(streams, turns)
        if not self.use_cache:
            history = [torch.cat(h) if count > 1 else h[0] for h in zip(*(list(s.turns) for s in streams))]
            tokens = torch.cat([*history, current], dim=1)
            for stream, own in zip(streams, self._per_stream(current, count)):
                stream.turns.append(self._as_history(own))
            return self._sample(streams, self.model.encode(tokens, context)[:, -1:])
        cond, kv = self.model.encode_next_turn(current, [self._batched_past(streams, layer)
                                                         for layer in range(len(self.model.blocks))])
        if context:
            for layer, (k, v) in enumerate(kv):
                for stream, k_s, v_s in zip(streams, self._per_stream(k, count), self._per_stream(v, count)):
                    stream.past[layer].append((self._as_history(k_s), self._as_history(v_s)))
        return self._sample(streams, cond)
