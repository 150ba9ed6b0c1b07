"""The offline protocol: a full-sequence (non-causal) model gets the whole clip at once.

The model receives read-only copies of the user's whole motion and speech and the agent's whole speech
(no agent motion) and returns the agent's motion for every frame of the clip. Results of such runs are
recorded with ``protocol = offline``; they are not comparable with streaming results.
"""

from __future__ import annotations

import time

import numpy as np

from dyadbench.datasets.base import DyadicClip
from dyadbench.protocol.config import ProtocolConfig
from dyadbench.protocol.interface import OfflineModel
from dyadbench.protocol.streaming import StreamOutput, readonly_window, check_output, stream_context


def run_offline(model: OfflineModel, clip: DyadicClip, agent: str, config: ProtocolConfig) -> StreamOutput:
    """Run ``model.predict_clip`` on one direction of ``clip``; output (T, D) with T = clip.num_frames."""
    ctx = stream_context(clip, agent, config)
    stem = f"{clip.clip_id}_{agent}"
    agent_p = clip.participant(agent)
    partner = clip.partner_of(agent)
    T = clip.num_frames
    samples = int(round(T * clip.sample_rate / clip.fps))
    user_motion = readonly_window(partner.motion, 0, T) if partner else np.zeros((T, 0), np.float32)
    user_audio = readonly_window(partner.audio, 0, samples) if partner else np.zeros(0, np.float32)
    start = time.perf_counter()
    out = model.predict_clip(ctx, user_motion, user_audio, readonly_window(agent_p.audio, 0, samples))
    latency = time.perf_counter() - start
    motion = check_output(out, (T, clip.motion_layout.dim), f"{model.info.name} on {stem} (offline)")
    return StreamOutput(stem=stem, motion=motion, turn_latency_s=[latency], num_turns=ctx.num_turns,
                        frames_per_turn=ctx.frames_per_turn, tail_frames=0, protocol="offline")
