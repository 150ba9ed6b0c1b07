"""Stage 1: contrastive pretraining of the style encoder (spec §2.8), and its retrieval check.

Adam on NT-Xent over batches of adjacent-window pairs (D22–D25); the weights with the lowest validation
NT-Xent (fixed, seeded validation batches) are kept (early-stopping selection).
"""

from __future__ import annotations

import time
import numpy as np
import torch
from torch import nn
from tqdm import tqdm

from dyadbench.motion import FPS
from dyadbench.seeding import derive_seed
from models.stygazetalk.config import MOTION_DIM, StyleEncoderConfig
from models.stygazetalk.data import Segment, sample_style_pairs, stacked_motion
from models.stygazetalk.normalise import ZScore
from models.stygazetalk.style_encoder import StyleEncoder, nt_xent
from models.stygazetalk.train_log import TrainLog

VAL_BATCHES = 8  # fixed validation batches of min(batch_pairs, 2 x sessions) pairs


class StyleModel(nn.Module):
    """The stage-1 artefact: train-split motion normaliser + style encoder."""

    def __init__(self, cfg: StyleEncoderConfig):
        super().__init__()
        self.cfg = cfg
        self.motion_norm = ZScore(MOTION_DIM)
        self.encoder = StyleEncoder(cfg)

    def embed_degrees(self, windows_deg: np.ndarray) -> np.ndarray:
        """Style vectors (n, d_s) of motion windows (n, M, 7) in degrees (eval mode, no gradients)."""
        self.eval()
        with torch.no_grad():
            x = self.motion_norm(torch.as_tensor(np.asarray(windows_deg, dtype=np.float32)))
            return self.encoder(x).numpy()


def _pair_tensors(segments: list[Segment], norm: list[np.ndarray], pairs, window: int) -> torch.Tensor:
    return torch.from_numpy(np.stack([norm[i][s:s + window] for i, s in pairs]))


def train_style_encoder(cfg: StyleEncoderConfig, train: list[Segment], val: list[Segment], *,
                        val_every: int = 50, progress: bool = True) -> tuple[StyleModel, TrainLog]:
    torch.manual_seed(derive_seed("stygazetalk-style", cfg.seed))
    model = StyleModel(cfg)
    model.motion_norm.load_state_dict(ZScore.fit(stacked_motion(train)).state_dict())
    norm_train = [model.motion_norm.np(s.motion) for s in train]
    norm_val = [model.motion_norm.np(s.motion) for s in val]
    gap = int(round(cfg.distinct_anchor_gap_s * FPS))
    sample = dict(window=cfg.window, gap_max=cfg.pair_gap_max, min_anchor_gap=gap)
    val_rng = np.random.default_rng(derive_seed("stygazetalk-style-val", cfg.seed))
    val_batches = []
    val_batch = min(cfg.batch_pairs, 2 * len({s.session for s in val}))  # small validation splits
    for _ in range(VAL_BATCHES):
        a, b = sample_style_pairs(val, val_rng, batch=val_batch, **sample)
        val_batches.append((_pair_tensors(val, norm_val, a, cfg.window), _pair_tensors(val, norm_val, b, cfg.window)))
    rng = np.random.default_rng(derive_seed("stygazetalk-style-train", cfg.seed))
    opt = torch.optim.Adam(model.encoder.parameters(), lr=cfg.lr)
    log, start = TrainLog(), time.perf_counter()
    for step in tqdm(range(1, cfg.steps + 1), desc=f"style {cfg.name}", disable=not progress or None):
        model.train()
        a, b = sample_style_pairs(train, rng, batch=cfg.batch_pairs, **sample)
        xa, xb = _pair_tensors(train, norm_train, a, cfg.window), _pair_tensors(train, norm_train, b, cfg.window)
        loss = nt_xent(model.encoder(xa), model.encoder(xb), cfg.temperature, cfg.loss_reduction)
        opt.zero_grad()
        loss.backward()
        opt.step()
        if step % val_every == 0 or step == cfg.steps:
            model.eval()
            with torch.no_grad():
                val_loss = float(np.mean([nt_xent(model.encoder(va), model.encoder(vb), cfg.temperature,
                                                  cfg.loss_reduction).item() for va, vb in val_batches]))
            log.record(step, loss.item(), val_loss, model)
    log.restore_best(model)
    model.eval()
    log.seconds = time.perf_counter() - start
    return model, log


def tiled_windows(segments: list[Segment], window: int) -> tuple[np.ndarray, list[str], list[str]]:
    """Non-overlapping windows (n, M, 7) in degrees with their speaker and session labels."""
    windows, speakers, sessions = [], [], []
    for seg in segments:
        for s in range(0, seg.frames - window + 1, window):
            windows.append(seg.motion[s:s + window])
            speakers.append(seg.speaker)
            sessions.append(seg.session)
    return np.stack(windows), speakers, sessions


def retrieval_accuracy(queries: np.ndarray, q_labels: list[str], gallery: np.ndarray | None = None,
                       g_labels: list[str] | None = None) -> tuple[float, float]:
    """Top-1 same-label accuracy of cosine nearest neighbours, and its chance level.

    Without a gallery, each query searches the other queries (leave-one-out); chance is then the mean
    over queries of the fraction of same-label candidates, which is what a random pick would score.
    """
    leave_one_out = gallery is None
    gallery, g_labels = (queries, q_labels) if leave_one_out else (gallery, g_labels)
    q = queries / np.linalg.norm(queries, axis=1, keepdims=True)
    g = gallery / np.linalg.norm(gallery, axis=1, keepdims=True)
    sim = q @ g.T
    same = np.asarray(q_labels)[:, None] == np.asarray(g_labels)[None, :]
    if leave_one_out:
        np.fill_diagonal(sim, -np.inf)
        np.fill_diagonal(same, False)
        candidates = len(g_labels) - 1
    else:
        candidates = len(g_labels)
    hits = same[np.arange(len(q_labels)), sim.argmax(axis=1)]
    return float(hits.mean()), float((same.sum(axis=1) / candidates).mean())
