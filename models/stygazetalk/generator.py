"""The StyGazeTalk motion generator (spec §2.1–2.6, §2.11): per-frame fusion Z = [Ã; X̃; s] into a
recurrent (LSTM, learned initial state) or causal-Transformer core, one output frame per step.

Window alignment (D5, one-frame lag): step i of a window reads the audio of frame u+i and the motion of
frame u+i−1, and predicts frame u+i. :meth:`MotionGenerator.forward` runs all M steps teacher-forced,
or switches to its own outputs from step ``free_from`` on (the autoregressive part of inference, and
rollout training, D9). Every window starts from the learned (h0, c0) [P §3.2].
:meth:`MotionGenerator.generate_blocks` generates the windows of several streams together (batched streaming)
with each row bit for bit its own :meth:`MotionGenerator.generate_block`.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Callable

import torch
from torch import nn

from models.stygazetalk.config import MOTION_DIM, GeneratorConfig
from models.stygazetalk.style_encoder import SinusoidalPositions


class LSTMCore(nn.Module):
    """Multi-layer LSTM whose initial hidden and cell states are learned parameters (D17)."""

    def __init__(self, in_dim: int, cfg: GeneratorConfig):
        super().__init__()
        self.lstm = nn.LSTM(in_dim, cfg.lstm_hidden, cfg.lstm_layers, batch_first=True,
                            dropout=cfg.lstm_dropout if cfg.lstm_layers > 1 else 0.0)
        shape = (cfg.lstm_layers, 1, cfg.lstm_hidden)
        self.h0 = nn.Parameter(torch.zeros(shape), requires_grad=cfg.learned_initial_state)
        self.c0 = nn.Parameter(torch.zeros(shape), requires_grad=cfg.learned_initial_state)
        self.out_dim = cfg.lstm_hidden

    def initial_state(self, batch: int) -> tuple[torch.Tensor, torch.Tensor]:
        return (self.h0.expand(-1, batch, -1).contiguous(), self.c0.expand(-1, batch, -1).contiguous())

    def forward(self, z: torch.Tensor, state: tuple[torch.Tensor, torch.Tensor]):
        return self.lstm(z, state)


class TransformerCore(nn.Module):
    """Causal Transformer replacing the LSTM (TFM-SE-64, D29). Its "state" is the input prefix so far."""

    def __init__(self, in_dim: int, cfg: GeneratorConfig):
        super().__init__()
        self.proj = nn.Linear(in_dim, cfg.tfm_d_model)
        self.positions = SinusoidalPositions(cfg.tfm_d_model)
        layer = nn.TransformerEncoderLayer(cfg.tfm_d_model, cfg.tfm_heads, cfg.tfm_ffn, cfg.tfm_dropout,
                                           activation="gelu", batch_first=True)
        self.encoder = nn.TransformerEncoder(layer, cfg.tfm_layers, enable_nested_tensor=False)
        self.out_dim = cfg.tfm_d_model

    def initial_state(self, batch: int) -> torch.Tensor | None:
        return None

    def forward(self, z: torch.Tensor, prefix: torch.Tensor | None):
        seq = z if prefix is None else torch.cat([prefix, z], dim=1)
        mask = nn.Transformer.generate_square_subsequent_mask(seq.shape[1], device=seq.device)
        h = self.encoder(self.positions(self.proj(seq)), mask=mask, is_causal=True)
        return h[:, -z.shape[1]:], seq


class MotionGenerator(nn.Module):
    """(audio features, previous motion, style) per frame → next motion frame, all normalised (D4)."""

    def __init__(self, cfg: GeneratorConfig, audio_dim: int):
        super().__init__()
        self.cfg = cfg.validate()
        self.audio_proj = nn.Linear(audio_dim, cfg.d)
        self.motion_proj = nn.Linear(MOTION_DIM, cfg.d)  # D6
        in_dim = 2 * cfg.d + cfg.style_dim
        self.core = LSTMCore(in_dim, cfg) if cfg.backbone == "lstm" else TransformerCore(in_dim, cfg)
        self.head = nn.Linear(self.core.out_dim, MOTION_DIM)  # D18

    def fuse(self, audio: torch.Tensor, motion: torch.Tensor, style: torch.Tensor | None) -> torch.Tensor:
        """Z = concatenation along features in ``cfg.concat_order`` (D19); s is repeated over time."""
        parts = {"audio": self.audio_proj(audio), "motion": self.motion_proj(motion)}
        if self.cfg.style:
            if style is None:
                raise ValueError(f"{self.cfg.name} conditions on a style vector; none was given")
            parts["style"] = style[:, None, :].expand(-1, audio.shape[1], -1)
        return torch.cat([parts[k] for k in self.cfg.concat_order if k in parts], dim=-1)

    def _emit(self, hidden: torch.Tensor, motion_in: torch.Tensor) -> torch.Tensor:
        y = self.head(hidden)
        return motion_in + y if self.cfg.residual_output else y

    def forward(self, audio: torch.Tensor, motion_in: torch.Tensor, style: torch.Tensor | None = None,
                free_from: int | None = None, draw: Callable[[torch.Tensor], torch.Tensor] | None = None
                ) -> torch.Tensor:
        """Outputs (B, M, 7) for audio (B, M, F) and motion inputs (B, ≥free_from, 7).

        Steps ``< free_from`` read ``motion_in`` (teacher forcing / known frames); later steps read the
        previous step's output. ``free_from=None`` teacher-forces all M steps. ``draw`` (sampled
        decoding) maps each free-running output — from step ``free_from − 1`` on — to the frame that
        is emitted and fed back.
        """
        steps = audio.shape[1]
        known = steps if free_from is None else free_from
        if not 1 <= known <= steps or motion_in.shape[1] < known:
            raise ValueError(f"free_from={free_from} needs 1..{steps} known steps; motion_in has {motion_in.shape[1]}")
        state = self.core.initial_state(audio.shape[0])
        hidden, state = self.core(self.fuse(audio[:, :known], motion_in[:, :known], style), state)
        outputs = [self._emit(hidden, motion_in[:, :known])]
        draw = draw if free_from is not None and draw is not None else (lambda frame: frame)
        prev = draw(outputs[0][:, -1:])
        outputs = [outputs[0][:, :-1], prev]
        for i in range(known, steps):
            hidden, state = self.core(self.fuse(audio[:, i:i + 1], prev, style), state)
            prev = draw(self._emit(hidden, prev))
            outputs.append(prev)
        return torch.cat(outputs, dim=1)

    def generate_block(self, audio: torch.Tensor, known: torch.Tensor, style: torch.Tensor | None,
                       draw: Callable[[torch.Tensor], torch.Tensor] | None = None) -> torch.Tensor:
        """N new frames (B, N, 7) of one inference window (D5).

        ``audio`` (B, M, F) covers frames u..u+M−1 with u = t − W; ``known`` (B, W+1, 7) holds the known
        frames x_{u−1}..x_{t−1}. The first W outputs re-predict known frames and are discarded.
        """
        warmup = self.cfg.warmup
        if known.shape[1] != warmup + 1:
            raise ValueError(f"generate_block needs W+1={warmup + 1} known frames, got {known.shape[1]}")
        return self.forward(audio, known, style, free_from=warmup + 1, draw=draw)[:, warmup:]

    def generate_blocks(self, audio: torch.Tensor, known: torch.Tensor, style: torch.Tensor | None,
                        draws: Sequence[Callable[[torch.Tensor], torch.Tensor] | None]) -> torch.Tensor:
        """:meth:`generate_block` of B windows (B, N, 7), row b bit for bit ``generate_block`` of row b alone
        with ``draws[b]`` (its stream's sampled decoding, or None).

        A matrix product over several rows can round differently from the same product over one row, and
        the autoregressive loop amplifies such a difference (degrees after a session), so only the work
        that is computed identically for one row and for many (measured with torch 2.13's CPU kernels, and
        checked by the tests) runs batched: the fusion and output head over the W+1 warm-up steps and each
        free-running LSTM step (and the style encoder, in
        :meth:`~models.stygazetalk.system.StyGazeTalkSystem.next_blocks`). The warm-up pass through the LSTM
        (a sequence kernel whose blocking depends on the batch), the one-frame projections (a matrix–vector
        product for one row) and the draws run row by row. The Transformer backbone runs its rows one at a
        time.
        """
        rows = audio.shape[0]
        if len(draws) != rows:
            raise ValueError(f"generate_blocks needs one draw per row: {len(draws)} for {rows} rows")
        styles = [None if style is None else style[b:b + 1] for b in range(rows)]
        if rows == 1 or not isinstance(self.core, LSTMCore):
            return torch.cat([self.generate_block(audio[b:b + 1], known[b:b + 1], styles[b], draws[b])
                              for b in range(rows)])
        warmup, steps = self.cfg.warmup, audio.shape[1]
        if known.shape[1] != warmup + 1:
            raise ValueError(f"generate_blocks needs W+1={warmup + 1} known frames, got {known.shape[1]}")
        fused = self.fuse(audio[:, :warmup + 1], known, style)
        first = [self.core(fused[b:b + 1], self.core.initial_state(1)) for b in range(rows)]
        hidden = torch.cat([h for h, _ in first])
        state = tuple(torch.cat([s[k] for _, s in first], dim=1) for k in range(2))
        prev = self._emit(hidden, known)[:, -1:]  # the head over all W+1 rows, as generate_block runs it
        prev = torch.cat([prev[b:b + 1] if draw is None else draw(prev[b:b + 1]) for b, draw in enumerate(draws)])
        outputs = [prev]
        for i in range(warmup + 1, steps):
            z = torch.cat([self.fuse(audio[b:b + 1, i:i + 1], prev[b:b + 1], styles[b]) for b in range(rows)])
            hidden, state = self.core(z, state)
            prev = torch.cat([self._draw_row(draws[b], self._emit(hidden[b:b + 1], prev[b:b + 1]))
                              for b in range(rows)])
            outputs.append(prev)
        return torch.cat(outputs, dim=1)

    @staticmethod
    def _draw_row(draw: Callable[[torch.Tensor], torch.Tensor] | None, frame: torch.Tensor) -> torch.Tensor:
        return frame if draw is None else draw(frame)
