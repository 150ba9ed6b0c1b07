"""SFMS as a dyadbench streaming listener model (spec §3.5, "dyadbench streaming protocol").

The agent is generated as a listener of its partner: each turn uses the partner's motion and speech of
the history and current turn (as sliced by the protocol; speech is the dataset's speech features where
it ships them, as Learning2Listen does, else the log-mel of the waveform) and the model's own committed classes from
earlier turns of the same stream (internal state, hence causal). The agent's own speech is not used.
Within a turn the model steps F = 8 frames at a time; a step crossing the turn end commits only the
frames inside the turn, and the speaker window never extends past the current turn.
"""

from __future__ import annotations

import numpy as np
import torch

from dyadbench.errors import InputError
from dyadbench.protocol.interface import ModelInfo, StreamContext, StreamingModel, TurnInput
from models.sfms.bundle import SFMS
from models.sfms.data import speaker_rows
from models.sfms.infer import Roller, speaker_window


class SFMSStreamingModel(StreamingModel):
    def __init__(self, model: SFMS, info: ModelInfo, *, greedy: bool | None = None):
        self.roller = Roller(model, greedy=greedy)
        self.tok, self.pred = model.tokenizer, model.predictor
        self.info = info
        self._ctx: StreamContext | None = None

    def start_stream(self, ctx: StreamContext) -> None:
        if ctx.user is None:
            raise InputError(ctx.clip_id, "SFMS is a listener model and needs a partner (two-participant clip)")
        self._ctx = ctx
        self._generator = torch.Generator().manual_seed(int(ctx.seed))
        self._hist = self.roller.neutral_history(1)

    def _inputs(self, turn: TurnInput) -> tuple[torch.Tensor, torch.Tensor]:
        """Normalised partner motion (1, N, d) and speech rows (1, N·rows, bins) of the turn window: the
        dataset's speech features when it ships them, else the log-mel of the partner's waveform."""
        ctx, cfg = self._ctx, self.pred.cfg
        n = turn.user_motion.shape[0]
        if turn.user_motion.ndim != 2 or turn.user_motion.shape[1] != self.tok.cfg.dim:
            raise InputError(f"{ctx.clip_id}_{ctx.user}", f"partner motion must be (T, {self.tok.cfg.dim}), "
                                                         f"got {turn.user_motion.shape}")
        motion = self.tok.normalise(torch.tensor(np.asarray(turn.user_motion), dtype=torch.float32))
        rows = speaker_rows(turn.user_speech_features, turn.user_audio, n, ctx.sample_rate, ctx.fps, cfg,
                            f"{ctx.clip_id}_{ctx.user}")
        need = n * cfg.audio_rows_per_frame
        rows = np.pad(rows[:need], ((0, max(need - rows.shape[0], 0)), (0, 0)))
        audio = (torch.as_tensor(rows) - self.pred.audio_mean) / self.pred.audio_std
        return motion[None], audio[None]

    @torch.no_grad()
    def predict_turn(self, turn: TurnInput) -> np.ndarray:
        if self._ctx is None:
            raise RuntimeError("predict_turn called before start_stream")
        cfg = self.pred.cfg
        speaker, audio = self._inputs(turn)
        known = speaker.shape[1]
        first = turn.history_turns * turn.frames_per_turn  # index of the current turn's first frame
        frames = []
        for t in range(first, known, cfg.future):
            n = min(cfg.future, known - t)
            m, a, valid = speaker_window(speaker, audio, known, t, cfg.past, cfg.future, cfg.audio_rows_per_frame)
            new, out = self.roller.step(self._hist, m, a, valid, n, self._generator)
            self._hist = torch.cat([self._hist, new], dim=1)[:, -cfg.past:]
            frames.append(out)
        return self.tok.denormalise(torch.cat(frames, dim=1)[0]).numpy().astype(np.float64)
