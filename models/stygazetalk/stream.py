"""StyGazeTalk under dyadbench's streaming protocol (spec §2.14).

- The agent's own speech drives the agent's motion; gaze–head sessions have no partner, so the user
  arrays are empty and ignored.
- **Seed window** (D28): the first M frames of the stream are the agent's ground truth, handed over
  by the protocol as ``TurnInput.agent_motion_oracle`` for the turns that lie entirely inside
  ``ModelInfo.seed_frames`` = M frames (M/F whole turns; the turn length must divide M). No later
  ground truth is ever read. The model
  returns them unchanged for those turns and every score skips them. With the MPGW-sim variant the
  seed's gaze dims are corrupted first (D30).
- After the seed, each turn is produced by N-frame windows (D5): the window's audio is the last
  W + N frames of speech up to the end of the current turn, cut from ``TurnInput.agent_audio``
  (zero-padded when the context holds fewer than ⌈W/F⌉ history turns); the motion inputs and the
  style window are the model's own most recent frames (seed, then its earlier outputs), which it keeps
  itself, whatever the protocol's history-agent policy.
- With sampled decoding (X1, an extension) the frames are drawn from a generator seeded by the
  protocol's per-stream seed, so a run is reproducible and causal.

Batched streaming (``predict_turns``): each stream keeps its own track (seed and own outputs), context and
generator; the windows the open streams generate at the same offset within their turns run as one batch
(:meth:`~models.stygazetalk.system.StyGazeTalkSystem.next_blocks`), row b drawing from stream b's generator
what it would draw alone, while seed turns are copied per stream. Turns of different frame counts run in
groups of equal length. Every stream's output is bit for bit what streaming it alone gives: the batch runs
only the arithmetic that rounds the same for one row and for many, the rest row by row
(:meth:`~models.stygazetalk.generator.MotionGenerator.generate_blocks`; a plain batched pass rounds the
one-frame products differently, and the autoregressive loop grows that into degrees over a session).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from dyadbench.errors import ConfigError, InputError
from dyadbench.motion import FPS, SAMPLE_RATE
from dyadbench.protocol.interface import ModelInfo, StatefulStreams, StreamContext, TurnInput
from models.stygazetalk.audio import HOP
from models.stygazetalk.generation import decoding_rng, mpgw_seed
from models.stygazetalk.system import StyGazeTalkSystem


@dataclass
class _Stream:
    """One stream's state: its context, decoding generator and motion track (seed, then own outputs)."""

    ctx: StreamContext
    rng: torch.Generator
    track: np.ndarray


class StyGazeTalkStream(StatefulStreams):
    def __init__(self, system: StyGazeTalkSystem, info: ModelInfo, style: torch.Tensor | None = None,
                 run_seed: int = 0):
        self.system, self.info, self.style, self.run_seed = system.eval(), info, style, run_seed
        super().__init__()

    def _new_stream(self, ctx: StreamContext) -> _Stream:
        if ctx.fps != FPS or ctx.sample_rate != SAMPLE_RATE:
            raise InputError(ctx.clip_id, f"StyGazeTalk runs at {FPS:g} fps / {SAMPLE_RATE} Hz, "
                                          f"got {ctx.fps:g} fps / {ctx.sample_rate} Hz")
        if self.system.cfg.window % ctx.frames_per_turn:
            raise ConfigError(f"the turn length ({ctx.frames_per_turn} frames) must divide the seed window "
                              f"M = {self.system.cfg.window}")
        return _Stream(ctx, decoding_rng(ctx.seed), np.zeros((ctx.num_turns * ctx.frames_per_turn, 7), np.float32))

    def _group_key(self, i: int, turn: TurnInput) -> object:
        """Turns of one length run as one batch."""
        return turn.frames_per_turn

    def _run(self, streams: list[_Stream], turns: list[TurnInput]) -> list[np.ndarray]:
        """The current turn of each stream (turns of one length): seed turns copied, the others generated window
        by window, the windows of all generating streams at one offset within the turn in one batch."""
        cfg, F = self.system.cfg, turns[0].frames_per_turn
        generating = []
        for stream, turn in zip(streams, turns):
            lo, hi = turn.turn * F, (turn.turn + 1) * F
            if hi <= cfg.window:
                stream.track[lo:hi] = self._seed_turn(turn, stream.ctx)
            else:
                generating.append((stream, turn))
        for offset in range(0, F, cfg.horizon) if generating else ():
            starts = [turn.turn * F + offset for _, turn in generating]  # each stream's first new frame t
            # the window's audio starts at u = t − W, relative to the first frame agent_audio covers
            waves = [_frames_of(turn.agent_audio, t - cfg.warmup - (turn.turn - turn.history_turns) * F, cfg.window)
                     for (_, turn), t in zip(generating, starts)]
            recents = [stream.track[t - cfg.window:t] for (stream, _), t in zip(generating, starts)]
            blocks = self.system.next_blocks(waves, recents, self.style, [stream.rng for stream, _ in generating])
            take = min(cfg.horizon, F - offset)
            for (stream, _), t, block in zip(generating, starts, blocks):
                stream.track[t:t + take] = block[:take]
        return [stream.track[turn.turn * F:(turn.turn + 1) * F].copy() for stream, turn in zip(streams, turns)]

    def _seed_turn(self, turn: TurnInput, ctx: StreamContext) -> np.ndarray:
        gt = turn.agent_motion_oracle
        if gt is None:
            raise ConfigError(f"{self.info.name}: the protocol handed no seed frames for turn {turn.turn}; "
                              f"StyGazeTalk needs the first M = {self.system.cfg.window} ground-truth "
                              f"frames as its seed window")
        seed = np.asarray(gt[-turn.frames_per_turn:], dtype=np.float32)
        if self.system.cfg.seed_window == "mpgw-sim":
            seed = mpgw_seed(seed, self.system.cfg.mpgw_bias_sd_deg, self.system.cfg.mpgw_noise_sd_deg,
                             self.run_seed, ctx.clip_id, offset=turn.turn * turn.frames_per_turn,
                             total=self.system.cfg.window)
        return seed


def _frames_of(audio: np.ndarray, first_frame: int, frames: int) -> np.ndarray:
    """Samples of ``frames`` frames starting at ``first_frame`` (relative to the array), zero outside it."""
    out = np.zeros(frames * HOP, np.float32)
    lo, hi = first_frame * HOP, (first_frame + frames) * HOP
    src_lo, src_hi = max(lo, 0), min(hi, audio.shape[0])
    if src_hi > src_lo:
        out[src_lo - lo:src_hi - lo] = audio[src_lo:src_hi]
    return out
