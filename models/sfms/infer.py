"""SFMS inference: autoregressive rolling 8 frames at a time, decoded by the frozen inpainter (spec §3.5).

:class:`Roller` holds the frozen model and does one step for a batch of streams: predict the classes of
the next F frames from the last P classes and the speaker window [t−P, t+F), sample them, decode the
48-class window with the tokenizer and emit its last frames (D30). :func:`roll` runs the loop over whole
sequences (offline, and the L2L-window protocol); the streaming adapter lives in :mod:`models.sfms.stream`.
All motion here is normalised (z-space); callers denormalise.
"""

from __future__ import annotations

import torch

from models.sfms.bundle import SFMS
from models.sfms.channel_tokens import from_rows, to_rows


class Roller:
    def __init__(self, model: SFMS, *, greedy: bool | None = None):
        self.model = model.eval()
        self.tok, self.pred = model.tokenizer, model.predictor
        self.cfg = self.pred.cfg
        self.greedy = self.cfg.sampling == "greedy" if greedy is None else greedy
        with torch.no_grad():
            neutral = torch.zeros(1, self.tok.cfg.window, self.tok.cfg.dim)
            self._neutral = self.tok.encode(neutral)[0][:, : self.cfg.past]

    def neutral_history(self, batch: int) -> torch.Tensor:
        """(batch, P) classes of an all-neutral past (the tokenised zero window); (batch, P, d) per channel."""
        return self._neutral.expand(batch, *self._neutral.shape[1:]).clone()

    def _sample(self, logits: torch.Tensor, generator: torch.Generator | list | None) -> torch.Tensor:
        """Classes of ``logits`` (B, ...); ``generator`` a list: one per row of the batch (row b draws from
        ``generator[b]`` exactly what it would draw alone)."""
        if self.greedy:
            return logits.argmax(-1)
        if isinstance(generator, list):
            return torch.cat([self._sample(logits[b:b + 1], g) for b, g in enumerate(generator)])
        logits = logits / self.cfg.temperature
        if self.cfg.top_k > 0:
            kth = logits.topk(min(self.cfg.top_k, logits.shape[-1]), dim=-1).values[..., -1:]
            logits = logits.masked_fill(logits < kth, float("-inf"))
        probs = torch.softmax(logits, dim=-1)
        flat = torch.multinomial(probs.reshape(-1, probs.shape[-1]), 1, generator=generator)
        return flat.reshape(probs.shape[:-1])

    def _cap(self, hist: torch.Tensor, new: torch.Tensor, logits: torch.Tensor) -> torch.Tensor:
        """D18: demote the least likely new keyframes to class 0 while the window exceeds the cap (per
        channel when the classes are per channel)."""
        if new.ndim == 3:
            d = new.shape[-1]
            flat_logits = logits.permute(0, 2, 1, 3).reshape(-1, logits.shape[1], logits.shape[-1])
            return from_rows(self._cap(to_rows(hist), to_rows(new), flat_logits), d)
        cap = self.cfg.keyframe_cap
        p_kf = 1.0 - torch.softmax(logits, -1)[..., 0]
        new = new.clone()
        for b in range(new.shape[0]):
            excess = int((hist[b] > 0).sum() + (new[b] > 0).sum()) - cap
            if excess > 0:
                kf = torch.nonzero(new[b] > 0).squeeze(-1)
                drop = kf[p_kf[b, kf].argsort()[: min(excess, len(kf))]]
                new[b, drop] = 0
        return new

    @torch.no_grad()
    def step(self, hist: torch.Tensor, speaker: torch.Tensor, audio: torch.Tensor, valid: torch.Tensor,
             n_commit: int, generator: torch.Generator | list | None = None) -> tuple[torch.Tensor, torch.Tensor]:
        """(new classes (B, n_commit), frames (B, n_commit, d)) for one step; ``hist`` (B, ≥P) (classes
        (B, n_commit, d) and ``hist`` (B, ≥P, d) with per-channel allocation); ``generator``: one for the
        batch, or a list of one per stream (:meth:`_sample`)."""
        past = hist[:, -self.cfg.past:]
        logits = self.pred(past, speaker, audio, valid)
        new = self._sample(logits, generator)
        if self.cfg.keyframe_cap is not None:
            new = self._cap(past, new, logits)
        frames = self.tok.decode(torch.cat([past, new], dim=1))[:, self.cfg.past:]
        return new[:, :n_commit], frames[:, :n_commit]


def speaker_window(speaker: torch.Tensor, audio: torch.Tensor, known: int, t: int, past: int, future: int,
                   rows: int) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Speaker motion (B, P+F, d), rows (B, (P+F)·rows, bins) and validity (B, P+F) for [t−P, t+F).

    Only frames 0 ≤ f < ``known`` of ``speaker`` (B, T, d) / ``audio`` (B, T·rows, bins) are read;
    others are zero and invalid.
    """
    b, _, d = speaker.shape
    w = past + future
    lo, hi = max(t - past, 0), min(t + future, known)
    off = lo - (t - past)
    m = speaker.new_zeros(b, w, d)
    a = audio.new_zeros(b, w * rows, audio.shape[-1])
    valid = torch.zeros(b, w, dtype=torch.bool)
    if hi > lo:
        m[:, off: off + hi - lo] = speaker[:, lo:hi]
        a[:, off * rows: (off + hi - lo) * rows] = audio[:, lo * rows: hi * rows]
        valid[:, off: off + hi - lo] = True
    return m, a, valid


@torch.no_grad()
def roll(roller: Roller, speaker: torch.Tensor, audio: torch.Tensor, start: int, stop: int,
         generator: torch.Generator | None = None, hist: torch.Tensor | None = None) -> torch.Tensor:
    """Generate listener frames [start, stop) (B, stop−start, d) from a neutral past at ``start``.

    The speaker (B, T, d) and its rows (B, T·rows, bins) are fully known (offline); step t reads
    speaker frames [t−P, t+F) only.
    """
    cfg = roller.cfg
    hist = roller.neutral_history(speaker.shape[0]) if hist is None else hist
    out = []
    for t in range(start, stop, cfg.future):
        n = min(cfg.future, stop - t)
        m, a, valid = speaker_window(speaker, audio, speaker.shape[1], t, cfg.past, cfg.future,
                                     cfg.audio_rows_per_frame)
        new, frames = roller.step(hist, m, a, valid, n, generator)
        hist = torch.cat([hist, new], dim=1)[:, -cfg.past:]
        out.append(frames)
    return torch.cat(out, dim=1)
