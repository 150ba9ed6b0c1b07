"""Scoring pieces of the SFMS Table III/IV ablations: windows with their listening-frame masks, the
reconstruction MSE over whole windows and over listening frames, and the bits a window's tokens carry.

- **Listening frames** are :func:`models.sfms.l2l_compare.listening_frames` (the agent silent and its
  partner speaking, from the clip's ``meta["speaking"]``): the frames a listening-head model is asked for.
  The same definition scores SFMS in ``sfms_l2l.md --frames listening``.
- **Bits per window** (one formula for every arm): tokens · log2(codebook size) + (sets of learned
  positions) · log2 C(T, k). A shared dynamic mask is one learned set of k positions among T frames;
  per-channel allocation learns one set per channel (d sets); static, dense and grouped (VQ-VAE) arms
  have fixed positions (0 sets).
"""

from __future__ import annotations

import math
from typing import Iterable

import numpy as np
import torch

from dyadbench.datasets.base import DyadicClip
from models.sfms.l2l_compare import listening_frames
from models.sfms.train_tokenizer import eval_windows


def window_bits(tokens: int, n_codes: int, position_sets: int = 0, window: int = 48, k: int = 0) -> float:
    """Bits per window: ``tokens``·log2(``n_codes``) + ``position_sets``·log2 C(``window``, ``k``)."""
    if tokens < 0 or n_codes < 1 or position_sets < 0 or not 0 <= k <= window:
        raise ValueError(f"window_bits: need tokens ≥ 0, codes ≥ 1, position sets ≥ 0 and 0 ≤ k ≤ window, got "
                         f"{tokens}, {n_codes}, {position_sets}, k = {k}, window = {window}")
    return tokens * math.log2(n_codes) + position_sets * math.log2(math.comb(window, k))


def agent_motions_and_masks(clips: Iterable[DyadicClip], mean: np.ndarray, std: np.ndarray
                            ) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """For every agent participant of every clip: its motion z-scored with (``mean``, ``std``) (float32) and
    its (T,) bool listening-frame mask."""
    motions, masks = [], []
    for clip in clips:
        for agent in clip.agent_participants:
            motions.append(((np.asarray(agent.motion, np.float32) - mean) / std).astype(np.float32))
            masks.append(listening_frames(clip, agent.name))
    return motions, masks


def masked_windows(motions: list[np.ndarray], masks: list[np.ndarray], window: int, limit: int
                   ) -> tuple[np.ndarray, np.ndarray]:
    """Non-overlapping ``window``-frame windows (N, T, d) of ``motions`` (at most ``limit``, in order) and
    the matching (N, T) bool windows of ``masks`` (:func:`eval_windows` cuts both)."""
    if len(motions) != len(masks) or any(m.shape[0] != k.shape[0] for m, k in zip(motions, masks)):
        raise ValueError("masked_windows: every motion needs a frame mask of its length")
    windows = eval_windows(motions, window, limit=limit)
    frames = eval_windows([k.astype(np.float32)[:, None] for k in masks], window, limit=limit)[..., 0] > 0.5
    return windows, frames


def mse_by_cut(errors_z: np.ndarray, errors_raw: np.ndarray, masks: np.ndarray) -> dict[str, float]:
    """Mean per-frame squared errors (N, T) over whole windows and over the masked (listening) frames;
    NaN for the listening cut when no frame is masked."""
    n = int(masks.sum())
    return {"mse_z": float(errors_z.mean()), "mse_raw": float(errors_raw.mean()),
            "listen_mse_z": float(errors_z[masks].mean()) if n else float("nan"),
            "listen_mse_raw": float(errors_raw[masks].mean()) if n else float("nan"),
            "listen_frames": n, "frames": int(masks.size)}


@torch.no_grad()
def frame_errors(model: torch.nn.Module, windows: np.ndarray, batch: int = 256) -> tuple[np.ndarray, np.ndarray]:
    """Eval-mode per-frame squared error of ``model.reconstruct`` (mean over the d dims), (N, T) each:
    in the normalised space of ``windows`` and in raw units (``model.denormalise``)."""
    was_training = model.training
    model.eval()
    z_out, raw_out = [], []
    for i in range(0, len(windows), batch):
        m = torch.as_tensor(windows[i: i + batch])
        rec = model.reconstruct(m)
        z_out.append((rec - m).pow(2).mean(-1).numpy())
        raw_out.append((model.denormalise(rec) - model.denormalise(m)).pow(2).mean(-1).numpy())
    model.train(was_training)
    return np.concatenate(z_out), np.concatenate(raw_out)


def code_usage(codes: torch.Tensor, n_codes: int) -> float:
    """Fraction of the ``n_codes`` codebook entries that occur in ``codes``."""
    return float(torch.unique(codes.flatten()).numel()) / n_codes
