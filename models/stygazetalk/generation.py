"""Sliding-window generation of a whole session (spec §2.10) and the seed window (D28, D30).

The track starts with the seed window — the session's first M ground-truth frames ("initial motion
window") — and grows by N frames per window, each conditioned on the model's own earlier output.
The seed frames are returned as given; every score skips them (D28).
"""

from __future__ import annotations

import numpy as np
import torch

from dyadbench.seeding import derive_seed, rng
from models.stygazetalk.audio import window_audio
from models.stygazetalk.system import StyGazeTalkSystem

GAZE = slice(3, 7)


def mpgw_seed(seed_deg: np.ndarray, bias_sd: float, noise_sd: float, *parts: object, offset: int = 0,
              total: int | None = None) -> np.ndarray:
    """MPGW-sim seed (D30): an appearance-based gaze estimate in place of eye-tracked gaze.

    On the 4 gaze dims only: a constant bias N(0, bias_sd²) per eye and angle for the whole seed,
    white noise N(0, noise_sd²) per frame, then both eyes replaced by their mean (one cyclopean
    direction). The head dims are unchanged. Seeded by ``parts`` (e.g. run seed and session id);
    ``seed_deg`` may be rows [offset, offset + len) of a seed of ``total`` frames (streamed per turn).
    """
    total = len(seed_deg) + offset if total is None else total
    r = rng("mpgw-seed", *parts)
    bias = r.normal(0.0, bias_sd, size=(1, 4))
    noise = r.normal(0.0, noise_sd, size=(total, 4))[offset:offset + len(seed_deg)]
    out = np.array(seed_deg, dtype=np.float32, copy=True)
    gaze = out[:, GAZE] + bias + noise
    mean = 0.5 * (gaze[:, 0:2] + gaze[:, 2:4])
    out[:, GAZE] = np.concatenate([mean, mean], axis=1)
    return out


def decoding_rng(stream_seed: int) -> torch.Generator:
    """The per-stream generator of sampled decoding (X1), seeded from the protocol's stream seed."""
    return torch.Generator().manual_seed(derive_seed("stygazetalk-decoding", stream_seed))


def generate_session(system: StyGazeTalkSystem, audio: np.ndarray, seed_deg: np.ndarray, n_frames: int,
                     style: torch.Tensor | None = None, stream_seed: int = 0) -> np.ndarray:
    """Motion (n_frames, 7) in degrees: the M seed frames, then N-frame blocks until n_frames.

    ``audio`` is the session's speech; a last partial block reads zero-padded audio past its end and
    is cut to n_frames. ``style`` fixes the style vector (style transfer) instead of SE(last M frames).
    """
    m, n, w = system.cfg.window, system.cfg.horizon, system.cfg.warmup
    if seed_deg.shape[0] < m:
        raise ValueError(f"the seed window needs M={m} frames, got {seed_deg.shape[0]}")
    draws = decoding_rng(stream_seed)
    track = [np.asarray(seed_deg[:m], dtype=np.float32)]
    t = m
    while t < n_frames:
        recent = np.concatenate(track[-(m // n + 2):])[-m:]
        block = system.next_block(window_audio(audio, t - w, m), recent, style, draws)
        take = min(n, n_frames - t)
        track.append(block[:take])
        t += take
    return np.concatenate(track)[:n_frames]
