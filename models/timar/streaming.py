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
"""

from __future__ import annotations

from collections import deque

import numpy as np
import torch

from dyadbench.errors import ConfigError
from dyadbench.protocol.interface import ModelInfo, StreamContext, StreamingModel, TurnInput
from models.timar.backbone import KV
from models.timar.frontends import SpeechFrontend
from models.timar.model import TimarModel

GUIDANCE_NULLS = ("current-turn", "every-turn")


class _TimarStreamBase(StreamingModel):
    def __init__(self, model: TimarModel, frontend: SpeechFrontend, info: ModelInfo, *, cfg_scale: float = 1.0,
                 use_cache: bool = True, temperature: float = 1.0, clamp_variance: bool = True,
                 guidance_null: str = "current-turn", device: str = "cpu"):
        if guidance_null not in GUIDANCE_NULLS:
            raise ConfigError(f"guidance_null must be one of {', '.join(GUIDANCE_NULLS)}, got {guidance_null!r}")
        self.model = model.eval().to(device)
        self.frontend = frontend
        self.info = info
        self.cfg_scale = float(cfg_scale)
        self.use_cache = use_cache
        self.temperature = temperature
        self.clamp_variance = clamp_variance
        self.guidance_null = guidance_null
        self.device = torch.device(device)
        self._generator = torch.Generator()
        self._context = 0
        self._audio_stats: tuple = (None, None)

    def start_stream(self, ctx: StreamContext) -> None:
        cfg = self.model.cfg
        if ctx.user is None:
            raise ConfigError(f"{self.info.name} needs a partner (user); {ctx.clip_id} has one participant")
        if (ctx.frames_per_turn, ctx.samples_per_turn) != (cfg.frames_per_turn, cfg.samples_per_turn):
            raise ConfigError(f"{self.info.name} was trained on turns of {cfg.frames_per_turn} frames / "
                              f"{cfg.samples_per_turn} samples; the protocol gives {ctx.frames_per_turn} / "
                              f"{ctx.samples_per_turn} (use --turn-seconds 1 at 25 fps, 16 kHz)")
        if ctx.context_turns > cfg.max_context:
            raise ConfigError(f"{self.info.name} supports a context of at most {cfg.max_context} history turns, "
                              f"got {ctx.context_turns}")
        self._generator = torch.Generator().manual_seed(ctx.seed)
        self._context = ctx.context_turns
        self._audio_stats = (ctx.user_audio_stats, ctx.agent_audio_stats)  # set only with speech_norm "clip"
        self.frontend.sample_rate, self.frontend.fps = ctx.sample_rate, ctx.fps
        self._reset()

    def _reset(self) -> None:
        raise NotImplementedError

    @property
    def _branches(self) -> int:
        """1 (conditional) or 2 (conditional, unconditional) when guidance is on."""
        return 1 if self.cfg_scale == 1.0 else 2

    @torch.no_grad()
    def _tokens(self, user_motion: np.ndarray, user_audio: np.ndarray, agent_audio: np.ndarray,
                turns: int) -> torch.Tensor:
        """Tokens (branches, turns, L, D) of ``turns`` whole turns, agent motion masked."""
        F = self.model.cfg.frames_per_turn

        def t(x: np.ndarray) -> torch.Tensor:
            return torch.from_numpy(np.array(x, dtype=np.float32)).to(self.device).view(1, turns, F, -1)

        user_stats, agent_stats = self._audio_stats
        us = self.frontend.features(user_audio, turns, user_stats)
        as_ = self.frontend.features(agent_audio, turns, agent_stats)
        um = user_motion[:turns * F]
        user_null = torch.zeros(self._branches, turns, 2 * F, dtype=torch.bool, device=self.device)
        user_null[1:, -1:] = True  # the unconditional branch nulls the current (last) turn's user frames ...
        if self.guidance_null == "every-turn":
            user_null[1:] = True  # ... or those of every turn in the window
        b = self._branches
        return self.model.turn_tokens(t(us).expand(b, -1, -1, -1), t(um).expand(b, -1, -1, -1),
                                      t(as_).expand(b, -1, -1, -1), user_null=user_null)

    def _as_history(self, x: torch.Tensor) -> torch.Tensor:
        """What the current turn's tokens or keys/values (branches first) become once it is a history turn:
        with current-turn nulling the unconditional branch sees history as the conditional branch does."""
        return x if self.guidance_null == "every-turn" else x[:1].expand_as(x)

    def _current_tokens(self, turn: TurnInput) -> torch.Tensor:
        return self._tokens(turn.current_user_motion, turn.current_user_audio, turn.current_agent_audio, 1)

    def _sample(self, cond: torch.Tensor) -> np.ndarray:
        """Frames (F, 56) from the current turn's features (branches, 1, L, D)."""
        z = cond[:, 0, self.model.agent_slice]
        x = self.model.sample_frames(z, self._generator, self.cfg_scale, self.temperature, self.clamp_variance)
        return x.cpu().numpy().astype(np.float32)


class FaithfulStream(_TimarStreamBase):
    """``timar``: window-indexed positions; exact KV cache while the window grows (t <= n)."""

    def _reset(self) -> None:
        self._past: list[list[KV]] = [[] for _ in self.model.blocks]
        self._window: deque[torch.Tensor] = deque(maxlen=self._context)  # history turns' tokens

    @torch.no_grad()
    def predict_turn(self, turn: TurnInput) -> np.ndarray:
        if not self.use_cache:
            tokens = self._tokens(turn.user_motion, turn.user_audio, turn.agent_audio, turn.history_turns + 1)
            return self._sample(self.model.encode(tokens)[:, -1:])
        current = self._current_tokens(turn)
        history = list(self._window)
        self._window.append(self._as_history(current))
        if turn.turn <= self._context:  # window still starts at turn 0: earlier turns' states are final
            cond, kv = self.model.encode_next_turn(current, self._past)
            for layer, (k, v) in enumerate(kv):
                self._past[layer].append((self._as_history(k), self._as_history(v)))
            return self._sample(cond)
        self._past = [[] for _ in self.model.blocks]  # window slid: positions of every turn changed
        return self._sample(self.model.encode(torch.cat([*history, current], dim=1))[:, -1:])


class BandStream(_TimarStreamBase):
    """``timar-stream``: per-turn sliding band; every turn's keys/values are computed once."""

    def _reset(self) -> None:
        band = self._context
        self._past = [deque(maxlen=band) for _ in self.model.blocks]
        self._turns: deque[torch.Tensor] = deque(maxlen=len(self.model.blocks) * band)  # history tokens

    @torch.no_grad()
    def predict_turn(self, turn: TurnInput) -> np.ndarray:
        current = self._current_tokens(turn)
        if not self.use_cache:
            tokens = torch.cat([*self._turns, current], dim=1)
            self._turns.append(self._as_history(current))
            return self._sample(self.model.encode(tokens, self._context)[:, -1:])
        cond, kv = self.model.encode_next_turn(current, [list(p) for p in self._past])
        if self._context:
            for layer, (k, v) in enumerate(kv):
                self._past[layer].append((self._as_history(k), self._as_history(v)))
        return self._sample(cond)
