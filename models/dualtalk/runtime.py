"""DualTalk under dyadbench's two protocols.

- :class:`DualTalkOffline` (``dualtalk-offline``, recorded ``protocol = offline``): the published DualTalk
  protocol. The whole clip at once; each waveform normalised over the whole clip, as the release does.
- :class:`DualTalkStream` (``dualtalk``, recorded ``protocol = streaming``): the progressive-context
  streaming protocol as TIMAR evaluated DualTalk. For turn t the model runs on the window of the last
  min(t, n) + 1 turns the protocol hands over (both speakers' audio, the partner's motion) and the frames
  of the current turn are kept. Waveforms are normalised over that window (causal, default) or, when the
  run's ``speech_norm`` is ``"clip"``, with the whole-clip statistics the protocol supplies
  (``StreamContext.agent_audio_stats`` / ``user_audio_stats``; reads future audio, recorded as such).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
import torch

from dyadbench.errors import ConfigError, InputError
from dyadbench.protocol.interface import (ModelInfo, OfflineModel, StreamContext, StreamingModel, TurnInput,
                                          predict_in_groups)
from models.dualtalk.model import DualTalkModel
from models.dualtalk.speech import frame_count, logmel_input, normalise_waveform


class DualTalkRunner:
    """One forward pass of a :class:`DualTalkModel` (eval mode, no gradients) on numpy inputs."""

    def __init__(self, model: DualTalkModel, device: str = "cpu"):
        self.model = model.eval().to(device)
        self.device = device

    def _speech(self, normalised: np.ndarray, frames: int) -> torch.Tensor:
        if self.model.cfg.speech_frontend == "logmel":
            normalised = logmel_input(normalised, frames)
        return torch.from_numpy(normalised).unsqueeze(0).to(self.device)

    @torch.no_grad()
    def predict(self, agent_audio: np.ndarray, user_audio: np.ndarray, user_motion: np.ndarray, *,
                agent_stats: tuple[float, float] | None = None,
                user_stats: tuple[float, float] | None = None) -> np.ndarray:
        """(T', 56) float32 with T' = ceil(len(agent_audio) / 640); ``*_stats`` None: the audio's own."""
        speech1, speech2, motion, frames = self._inputs(agent_audio, user_audio, user_motion, agent_stats, user_stats)
        return self.model(speech1, speech2, motion, frames)[0].cpu().numpy()

    @torch.no_grad()
    def predict_many(self, windows: list[dict]) -> np.ndarray:
        """(B, T', 56): :meth:`predict` of each window (its keyword arguments) in one forward pass; the windows
        must be of one length."""
        inputs = [self._inputs(**window) for window in windows]
        frames = {x[3] for x in inputs}
        if len(frames) != 1:
            raise InputError("dualtalk", f"windows of one forward pass must be of one length, got {sorted(frames)} frames")
        speech1, speech2, motion = (torch.cat(parts) for parts in list(zip(*inputs))[:3])
        return self.model(speech1, speech2, motion, frames.pop()).cpu().numpy()

    def _inputs(self, agent_audio: np.ndarray, user_audio: np.ndarray, user_motion: np.ndarray,
                agent_stats: tuple[float, float] | None = None, user_stats: tuple[float, float] | None = None):
        """(agent speech, partner speech, partner motion, T'), each tensor with a batch dimension of 1."""
        if user_motion.ndim != 2 or user_motion.shape[1] != self.model.cfg.motion_dim or not len(user_audio):
            raise InputError("dualtalk", f"DualTalk needs a partner with speech and {self.model.cfg.motion_dim}-d "
                                         f"motion, got motion {user_motion.shape} and {len(user_audio)} samples")
        frames = frame_count(len(agent_audio))
        speech1 = self._speech(normalise_waveform(agent_audio, agent_stats), frames)
        speech2 = self._speech(normalise_waveform(user_audio, user_stats), frames)
        motion = torch.tensor(np.asarray(user_motion, dtype=np.float32)).unsqueeze(0).to(self.device)
        return speech1, speech2, motion, frames


def fit_length(motion: np.ndarray, frames: int) -> np.ndarray:
    """Cut to ``frames`` rows, or repeat the last row up to it."""
    if motion.shape[0] >= frames:
        return motion[:frames]
    return np.concatenate([motion, np.repeat(motion[-1:], frames - motion.shape[0], axis=0)])


class DualTalkOffline(OfflineModel):
    def __init__(self, runner: DualTalkRunner, info: ModelInfo):
        self.runner, self.info = runner, info

    def predict_clip(self, ctx: StreamContext, user_motion: np.ndarray, user_audio: np.ndarray,
                     agent_audio: np.ndarray) -> np.ndarray:
        return fit_length(self.runner.predict(agent_audio, user_audio, user_motion), len(user_motion))


class DualTalkStream(StreamingModel):
    """Stateless but for each stream's waveform statistics; ``predict_turns`` runs the turns whose windows are
    of one length (same t or both past n) in one forward pass."""

    def __init__(self, runner: DualTalkRunner, info: ModelInfo):
        self.runner, self.info = runner, info
        self.stats: dict[str, tuple[float, float] | None] = {}
        self._slot_stats: dict[int, dict[str, tuple[float, float] | None]] = {}

    def start_stream(self, ctx: StreamContext) -> None:
        self.stats = _stream_stats(ctx)

    def start_streams(self, contexts: Mapping[int, StreamContext]) -> None:
        self._slot_stats.update({slot: _stream_stats(ctx) for slot, ctx in contexts.items()})

    def predict_turn(self, turn: TurnInput) -> np.ndarray:
        out = self.runner.predict(turn.agent_audio, turn.user_audio, turn.user_motion, **self.stats)
        return _current(out, turn)

    def predict_turns(self, turns: Sequence[TurnInput]) -> list[np.ndarray]:
        def predict(members: list[int]) -> list[np.ndarray]:
            windows = [dict(agent_audio=turns[i].agent_audio, user_audio=turns[i].user_audio,
                            user_motion=turns[i].user_motion, **self._slot_stats[turns[i].stream]) for i in members]
            return [_current(motion, turns[i]) for i, motion in zip(members, self.runner.predict_many(windows))]

        def shapes(_, turn: TurnInput) -> tuple:
            return turn.agent_audio.shape[0], turn.user_audio.shape[0], turn.user_motion.shape[0]

        return predict_in_groups(turns, shapes, predict)


def _stream_stats(ctx: StreamContext) -> dict[str, tuple[float, float] | None]:
    """The waveform statistics ``DualTalkRunner.predict`` gets for a stream: none (each window's own) or the
    whole clip's under speech_norm "clip"."""
    if ctx.speech_norm == "clip":
        if ctx.agent_audio_stats is None or ctx.user_audio_stats is None:
            raise ConfigError("speech_norm 'clip' needs the whole-clip waveform statistics of both speakers")
        return {"agent_stats": ctx.agent_audio_stats, "user_stats": ctx.user_audio_stats}
    if ctx.speech_norm == "window":
        return {}
    raise ConfigError(f"unknown speech_norm {ctx.speech_norm!r} (window or clip)")


def _current(window_motion: np.ndarray, turn: TurnInput) -> np.ndarray:
    """The current turn's frames of the motion predicted for the whole window."""
    return fit_length(window_motion, (turn.history_turns + 1) * turn.frames_per_turn)[-turn.frames_per_turn:]
