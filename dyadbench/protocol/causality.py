"""Causality check for streaming models: outputs up to turn t must not depend on anything after turn t.

:func:`check_causal` streams a clip twice through fresh models from ``model_factory`` — once as is and
once with every input after turn t replaced (both participants' motion, speech and speech features:
seeded Gaussian noise at a different scale and offset) — and requires the outputs of turns 0..t to be
identical. For a model that is not an oracle the agent's ground-truth motion is replaced over the whole
clip as well (after its seed window, ``ModelInfo.seed_frames``): the protocol never hands it to such a
model, so nothing may change. Every model's tests call this.

Under ``speech_norm = clip`` the protocol hands each stream the whole clip's waveform mean and variance,
a declared read of future audio (such runs are recorded as not strictly causal). The check then gives
the perturbed run the unperturbed clip's statistics, so it still proves that nothing else leaks.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Callable

import numpy as np

from dyadbench.datasets.base import DyadicClip, Participant
from dyadbench.errors import ConfigError
from dyadbench.protocol.config import ProtocolConfig
from dyadbench.protocol.interface import StreamingModel
from dyadbench.protocol.streaming import stream_agent, stream_agents
from dyadbench.seeding import rng


class CausalityViolation(AssertionError):
    """A model's output up to turn t changed when inputs after turn t changed."""


def perturb_after(clip: DyadicClip, first_frame: int, *, agent: str | None = None, agent_from: int = 0,
                  seed: int = 0) -> DyadicClip:
    """A copy of ``clip`` whose motion from ``first_frame``, audio from the matching sample and speech
    features from the matching row are replaced.

    Replacement values are seeded Gaussian noise with 3x the array's scale plus an offset, so any read of
    them shows. When ``agent`` is given, that participant's motion is replaced from frame ``agent_from``
    (0, or the end of the model's seed window).
    """
    first_sample = int(round(first_frame * clip.sample_rate / clip.fps))
    participants = []
    for p in clip.participants:
        gen = rng(seed, clip.clip_id, p.name)
        motion_from = min(agent_from, first_frame) if p.name == agent else first_frame
        r = p.feature_rows_per_frame
        participants.append(Participant(
            p.name, _replace_from(p.motion, motion_from, gen), _replace_from(p.audio, first_sample, gen),
            p.identity, None if r is None else _replace_from(p.speech_features, first_frame * r, gen)))
    return replace(clip, participants=tuple(participants))


def check_causal(model_factory: Callable[[], StreamingModel], clip: DyadicClip, agent: str,
                 config: ProtocolConfig, turn: int, *, batched: bool = False) -> None:
    """Raise :class:`CausalityViolation` if outputs of turns 0..``turn`` change when later inputs change.

    ``model_factory`` must return a fresh model (same weights, same options) on each call. ``batched``: the
    original and the perturbed clip stream together through one model (``predict_turns``, two slots), so
    the check also catches a batch whose streams read each other's inputs.
    """
    frames = config.frames_per_turn(clip.fps)
    num_turns = clip.num_frames // frames
    if not 0 <= turn < num_turns - 1:
        raise ConfigError(f"turn must be in 0..{num_turns - 2} so that later turns exist "
                          f"({clip.clip_id} has {num_turns} turns), got {turn}")
    model = model_factory()
    if not isinstance(model, StreamingModel):
        raise ConfigError(f"{type(model).__name__} is not a StreamingModel; causality applies to streaming models")
    oracle = bool(model.info.oracle)
    changed = perturb_after(clip, (turn + 1) * frames, agent=None if oracle else agent,
                            agent_from=int(model.info.seed_frames), seed=config.seed)
    fixed_stats = {"stats_clip": clip} if config.speech_norm == "clip" else {}
    if batched:
        reference, perturbed = (out.motion for out in stream_agents(
            model, [(clip, agent), (changed, agent, fixed_stats.get("stats_clip"))], config, batch=2))
    else:
        reference = stream_agent(model, clip, agent, config).motion
        perturbed = stream_agent(model_factory(), changed, agent, config, **fixed_stats).motion

    upto = (turn + 1) * frames
    a, b = reference[:upto], perturbed[:upto]
    if not np.array_equal(a, b):
        diff = np.abs(a.astype(np.float64) - b.astype(np.float64))
        frame = int(np.argwhere(diff > 0)[0][0]) if (diff > 0).any() else int(np.argwhere(a != b)[0][0])
        what = "inputs after turn" if oracle else "inputs after turn (or the agent's ground truth, never given)"
        raise CausalityViolation(
            f"{model.info.name} on {clip.clip_id}_{agent}: output up to turn {turn} changed when {what} "
            f"{turn} were perturbed; first differing frame {frame} (turn {frame // frames}), "
            f"max |difference| {float(np.nanmax(diff)):.3g}")


def _replace_from(array: np.ndarray, start: int, gen: np.random.Generator) -> np.ndarray:
    out = np.array(array, copy=True)
    n = out.shape[0] - start
    if n <= 0:
        return out
    scale = float(np.std(out)) if out.size else 1.0
    noise = gen.standard_normal((n,) + out.shape[1:]) * 3.0 * (scale or 1.0) + 0.5 * (scale or 1.0)
    out[start:] = noise.astype(out.dtype)
    return out
