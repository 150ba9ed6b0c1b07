"""SFMS as a dyadbench streaming listener model (spec §3.5, "dyadbench streaming protocol").

The agent is generated as a listener of its partner: each turn uses the partner's motion and speech of
the history and current turn (as sliced by the protocol; speech is the dataset's speech features where
it ships them, as Learning2Listen does, else the log-mel of the waveform) and the model's own committed classes from
earlier turns of the same stream (internal state, hence causal). The agent's own speech is not used.
Within a turn the model steps F = 8 frames at a time; a step crossing the turn end commits only the
frames inside the turn, and the speaker window never extends past the current turn.

Batched streaming (``predict_turns``): the open streams' steps run as one batch through the predictor and
the tokenizer, each stream with its own committed classes and its own random generator (seeded from its
stream seed; row b of the batch draws from stream b's generator what it would draw alone): bit for bit
the outputs of streaming each direction alone with the shared keyframe mask (``mask_sharing = frame``, the
default). Streams whose turns have different frame counts run in groups of equal turn length. With
per-channel allocation (``mask_sharing = channel``) a batch of (frame, channel) tokens rounds differently
(about 4e-7 in normalised motion, measured), so those streams run one at a time (each with its own state),
which keeps them bit for bit too.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from dyadbench.errors import InputError
from dyadbench.protocol.interface import ModelInfo, StatefulStreams, StreamContext, TurnInput
from models.sfms.bundle import SFMS
from models.sfms.data import speaker_rows
from models.sfms.infer import Roller, speaker_window


@dataclass
class _Stream:
    """One stream's state: its context, random generator and last P committed classes (1, P[, d])."""

    ctx: StreamContext
    generator: torch.Generator
    hist: torch.Tensor


class SFMSStreamingModel(StatefulStreams):
    def __init__(self, model: SFMS, info: ModelInfo, *, greedy: bool | None = None):
        self.roller = Roller(model, greedy=greedy)
        self.tok, self.pred = model.tokenizer, model.predictor
        self.info = info
        super().__init__()

    def _new_stream(self, ctx: StreamContext) -> _Stream:
        if ctx.user is None:
            raise InputError(ctx.clip_id, "SFMS is a listener model and needs a partner (two-participant clip)")
        return _Stream(ctx, torch.Generator().manual_seed(int(ctx.seed)), self.roller.neutral_history(1))

    def _inputs(self, turn: TurnInput, ctx: StreamContext) -> tuple[torch.Tensor, torch.Tensor]:
        """Normalised partner motion (1, N, d) and speech rows (1, N·rows, bins) of the turn window: the
        dataset's speech features when it ships them, else the log-mel of the partner's waveform."""
        cfg = self.pred.cfg
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

    def _group_key(self, i: int, turn: TurnInput) -> object:
        """Turns run as one batch share a key: equal turn lengths (per-channel allocation: each turn alone,
        see the module docstring)."""
        return ("alone", i) if self.tok.cfg.per_channel else turn.frames_per_turn

    @torch.no_grad()
    def _run(self, streams: list[_Stream], turns: list[TurnInput]) -> list[np.ndarray]:
        """The current turn of each stream (turns of one length), the streams' steps batched: step k of the
        turn reads each stream's speaker window at its own frame h·F + k·future (h its history turns)."""
        cfg = self.pred.cfg
        inputs = [self._inputs(turn, stream.ctx) for turn, stream in zip(turns, streams)]
        length = turns[0].frames_per_turn
        hist = torch.cat([stream.hist for stream in streams])
        frames = []
        for k in range(0, length, cfg.future):
            windows = [speaker_window(speaker, audio, speaker.shape[1], turn.history_turns * length + k, cfg.past,
                                      cfg.future, cfg.audio_rows_per_frame)
                       for (speaker, audio), turn in zip(inputs, turns)]
            m, a, valid = (torch.cat(parts) for parts in zip(*windows))
            new, out = self.roller.step(hist, m, a, valid, min(cfg.future, length - k),
                                        [stream.generator for stream in streams])
            hist = torch.cat([hist, new], dim=1)[:, -cfg.past:]
            frames.append(out)
        for b, stream in enumerate(streams):
            stream.hist = hist[b:b + 1]
        motion = torch.cat(frames, dim=1)
        return [self.tok.denormalise(motion[b]).numpy().astype(np.float64) for b in range(len(streams))]
