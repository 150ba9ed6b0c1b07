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

import numpy as np
import torch

from dyadbench.errors import ConfigError, InputError
from dyadbench.protocol.interface import ModelInfo, OfflineModel, StreamContext, StreamingModel, TurnInput
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
        if user_motion.ndim != 2 or user_motion.shape[1] != self.model.cfg.motion_dim or not len(user_audio):
            raise InputError("dualtalk", f"DualTalk needs a partner with speech and {self.model.cfg.motion_dim}-d "
                                         f"motion, got motion {user_motion.shape} and {len(user_audio)} samples")
        frames = frame_count(len(agent_audio))
        speech1 = self._speech(normalise_waveform(agent_audio, agent_stats), frames)
        speech2 = self._speech(normalise_waveform(user_audio, user_stats), frames)
        motion = torch.tensor(np.asarray(user_motion, dtype=np.float32)).unsqueeze(0).to(self.device)
        return self.model(speech1, speech2, motion, frames)[0].cpu().numpy()


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
    def __init__(self, runner: DualTalkRunner, info: ModelInfo):
        self.runner, self.info = runner, info
        self.stats: dict[str, tuple[float, float] | None] = {}

    def start_stream(self, ctx: StreamContext) -> None:
        if ctx.speech_norm == "clip":
            if ctx.agent_audio_stats is None or ctx.user_audio_stats is None:
                raise ConfigError("speech_norm 'clip' needs the whole-clip waveform statistics of both speakers")
            self.stats = {"agent_stats": ctx.agent_audio_stats, "user_stats": ctx.user_audio_stats}
        elif ctx.speech_norm == "window":
            self.stats = {}
        else:
            raise ConfigError(f"unknown speech_norm {ctx.speech_norm!r} (window or clip)")

    def predict_turn(self, turn: TurnInput) -> np.ndarray:
        out = self.runner.predict(turn.agent_audio, turn.user_audio, turn.user_motion, **self.stats)
        return fit_length(out, (turn.history_turns + 1) * turn.frames_per_turn)[-turn.frames_per_turn:]
