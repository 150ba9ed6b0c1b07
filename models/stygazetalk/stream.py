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
"""

from __future__ import annotations

import numpy as np
import torch

from dyadbench.errors import ConfigError, InputError
from dyadbench.motion import FPS, SAMPLE_RATE
from dyadbench.protocol.interface import ModelInfo, StreamContext, StreamingModel, TurnInput
from models.stygazetalk.audio import HOP
from models.stygazetalk.generation import decoding_rng, mpgw_seed
from models.stygazetalk.system import StyGazeTalkSystem


class StyGazeTalkStream(StreamingModel):
    def __init__(self, system: StyGazeTalkSystem, info: ModelInfo, style: torch.Tensor | None = None,
                 run_seed: int = 0):
        self.system, self.info, self.style, self.run_seed = system.eval(), info, style, run_seed
        self._track = np.zeros((0, 7), np.float32)
        self._ctx: StreamContext | None = None
        self._rng = decoding_rng(0)

    def start_stream(self, ctx: StreamContext) -> None:
        if ctx.fps != FPS or ctx.sample_rate != SAMPLE_RATE:
            raise InputError(ctx.clip_id, f"StyGazeTalk runs at {FPS:g} fps / {SAMPLE_RATE} Hz, "
                                          f"got {ctx.fps:g} fps / {ctx.sample_rate} Hz")
        if self.system.cfg.window % ctx.frames_per_turn:
            raise ConfigError(f"the turn length ({ctx.frames_per_turn} frames) must divide the seed window "
                              f"M = {self.system.cfg.window}")
        self._ctx = ctx
        self._rng = decoding_rng(ctx.seed)
        self._track = np.zeros((ctx.num_turns * ctx.frames_per_turn, 7), np.float32)

    def predict_turn(self, turn: TurnInput) -> np.ndarray:
        cfg, F = self.system.cfg, turn.frames_per_turn
        lo, hi = turn.turn * F, (turn.turn + 1) * F
        if hi <= cfg.window:
            self._track[lo:hi] = self._seed_turn(turn)
            return self._track[lo:hi].copy()
        audio_start = (turn.turn - turn.history_turns) * F  # first frame covered by agent_audio
        t = lo
        while t < hi:
            u = t - cfg.warmup
            wave = _frames_of(turn.agent_audio, u - audio_start, cfg.window)
            block = self.system.next_block(wave, self._track[t - cfg.window:t], self.style, self._rng)
            take = min(cfg.horizon, hi - t)
            self._track[t:t + take] = block[:take]
            t += take
        return self._track[lo:hi].copy()

    def _seed_turn(self, turn: TurnInput) -> np.ndarray:
        gt = turn.agent_motion_oracle
        if gt is None:
            raise ConfigError(f"{self.info.name}: the protocol handed no seed frames for turn {turn.turn}; "
                              f"StyGazeTalk needs the first M = {self.system.cfg.window} ground-truth "
                              f"frames as its seed window")
        seed = np.asarray(gt[-turn.frames_per_turn:], dtype=np.float32)
        if self.system.cfg.seed_window == "mpgw-sim":
            seed = mpgw_seed(seed, self.system.cfg.mpgw_bias_sd_deg, self.system.cfg.mpgw_noise_sd_deg,
                             self.run_seed, self._ctx.clip_id, offset=turn.turn * turn.frames_per_turn,
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
