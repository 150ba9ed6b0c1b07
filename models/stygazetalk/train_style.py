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


def _pair_labels(segments: list[Segment], pairs, cfg: StyleEncoderConfig) -> torch.Tensor | None:
    """Speaker index of each pair when same-speaker windows are not negatives (D46), else None."""
    if cfg.negatives == "all":
        return None
    speakers = sorted({s.speaker for s in segments})
    return torch.tensor([speakers.index(segments[i].speaker) for i, _ in pairs])


def train_style_encoder(cfg: StyleEncoderConfig, train: list[Segment], val: list[Segment], *,
                        val_every: int = 50, progress: bool = True, device: str = "cpu") -> tuple[StyleModel, TrainLog]:
    """Train the style encoder on ``device`` (batches are drawn on the CPU, seeded alike on every device);
    returns the selected weights on the CPU, in eval mode, and the training log."""
    torch.manual_seed(derive_seed("stygazetalk-style", cfg.seed))
    model = StyleModel(cfg)
    model.motion_norm.load_state_dict(ZScore.fit(stacked_motion(train)).state_dict())
    norm_train = [model.motion_norm.np(s.motion) for s in train]
    if cfg.input_features == "centred+velocity":  # D47: unit-rms velocity channels
        diffs = np.concatenate([np.diff(x, axis=0) for x in norm_train])
        model.encoder.velocity_scale.copy_(torch.from_numpy(np.sqrt((diffs ** 2).mean(axis=0)).astype(np.float32)))
    norm_val = [model.motion_norm.np(s.motion) for s in val]
    gap = int(round(cfg.distinct_anchor_gap_s * FPS))
    sample = dict(window=cfg.window, gap_max=cfg.pair_gap_max, min_anchor_gap=gap, positives=cfg.positives)
    val_rng = np.random.default_rng(derive_seed("stygazetalk-style-val", cfg.seed))
    val_batches = []
    val_batch = min(cfg.batch_pairs, 2 * len({s.session for s in val}))  # small validation splits
    for _ in range(VAL_BATCHES):
        a, b = sample_style_pairs(val, val_rng, batch=val_batch, **sample)
        val_batches.append((_pair_tensors(val, norm_val, a, cfg.window).to(device),
                            _pair_tensors(val, norm_val, b, cfg.window).to(device), _pair_labels(val, a, cfg)))
    rng = np.random.default_rng(derive_seed("stygazetalk-style-train", cfg.seed))
    model.to(device)
    opt = torch.optim.Adam(model.encoder.parameters(), lr=cfg.lr)
    log, start = TrainLog(), time.perf_counter()
    for step in tqdm(range(1, cfg.steps + 1), desc=f"style {cfg.name}", disable=not progress or None):
        model.train()
        a, b = sample_style_pairs(train, rng, batch=cfg.batch_pairs, **sample)
        xa = _pair_tensors(train, norm_train, a, cfg.window).to(device)
        xb = _pair_tensors(train, norm_train, b, cfg.window).to(device)
        loss = nt_xent(model.encoder(xa), model.encoder(xb), cfg.temperature, cfg.loss_reduction,
                       _pair_labels(train, a, cfg))
        opt.zero_grad()
        loss.backward()
        opt.step()
        if step % val_every == 0 or step == cfg.steps:
            model.eval()
            with torch.no_grad():
                val_loss = float(np.mean([nt_xent(model.encoder(va), model.encoder(vb), cfg.temperature,
                                                  cfg.loss_reduction, vl).item() for va, vb, vl in val_batches]))
            log.record(step, loss.item(), val_loss, model)
    log.restore_best(model)
    model.cpu().eval()
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
                       g_labels: list[str] | None = None, *, q_sessions: list[str] | None = None,
                       g_sessions: list[str] | None = None) -> tuple[float, float]:
    """Top-1 same-label accuracy of cosine nearest neighbours, and its chance level.

    Without a gallery, each query searches the other queries (leave-one-out). With ``q_sessions`` and
    ``g_sessions``, gallery windows of the query's own session are never candidates: the cross-session
    protocol, where a hit needs the speaker's style and not what one recording shares (within a session
    the nearest window is usually from the same session, so the plain leave-one-out over one session per
    speaker measures session identity). Chance is the mean over queries of the fraction of same-label
    candidates, which is what a random pick would score.
    """
    leave_one_out = gallery is None
    gallery, g_labels = (queries, q_labels) if leave_one_out else (gallery, g_labels)
    if (q_sessions is None) != (g_sessions is None):
        raise ValueError("give both q_sessions and g_sessions, or neither")
    if leave_one_out and q_sessions is not None:
        g_sessions = q_sessions
    q = queries / np.linalg.norm(queries, axis=1, keepdims=True)
    g = gallery / np.linalg.norm(gallery, axis=1, keepdims=True)
    sim = q @ g.T
    same = np.asarray(q_labels)[:, None] == np.asarray(g_labels)[None, :]
    allowed = np.ones_like(same)
    if leave_one_out:
        np.fill_diagonal(allowed, False)
    if q_sessions is not None:
        allowed &= np.asarray(q_sessions)[:, None] != np.asarray(g_sessions)[None, :]
    if not allowed.any(axis=1).all():
        raise ValueError("a query has no gallery window outside its own session")
    sim = np.where(allowed, sim, -np.inf)
    hits = same[np.arange(len(q_labels)), sim.argmax(axis=1)]
    chance = ((same & allowed).sum(axis=1) / allowed.sum(axis=1)).mean()
    return float(hits.mean()), float(chance)


def cross_session_retrieval(model: StyleModel, queries: list[Segment], gallery: list[Segment]) -> tuple[float, float]:
    """The documented speaker-retrieval protocol: non-overlapping M-frame windows of ``queries`` searched
    (cosine, top-1) among the windows of ``gallery`` from other sessions; returns (accuracy, chance)."""
    wq, sq, eq = tiled_windows(queries, model.cfg.window)
    wg, sg, eg = tiled_windows(gallery, model.cfg.window)
    return retrieval_accuracy(model.embed_degrees(wq), sq, model.embed_degrees(wg), sg, q_sessions=eq, g_sessions=eg)
