"""Stage 1 of SFMS: the sparse facial motion structure tokenizer (spec §2).

A window m (B, T, d) of normalised motion is scored per frame (:class:`KeyframeScorer`), k keyframes
are picked (Gumbel soft top-k while training, deterministic top-k otherwise), only keyframes are
encoded and quantised (FSQ or VQ), and the inpainter (transition encoder + decoder) rebuilds every
frame from the quantised keyframes and their positions. Transition-frame inputs are never read.

Per-frame classes: 0 = transition frame, 1 + code index = keyframe (``encode`` / ``decode``). With
per-channel allocation (``mask_sharing = "channel"``, :mod:`models.sfms.channel_tokens`) every channel
has its own k keyframes and classes are per (frame, channel), shape (B, T, d).
"""

from __future__ import annotations

import torch
from torch import nn

from models.sfms.channel_tokens import from_rows, gather_tokens, scatter_tokens, to_rows
from models.sfms.config import TokenizerConfig
from models.sfms.fsq import FSQ
from models.sfms.layers import CrossStack, EncoderStack, positions, with_sink
from models.sfms.topk import dense_mask, gumbel_soft_topk, hard_topk, relaxed_topk, static_mask
from models.sfms.vq import VQ


class KeyframeScorer(nn.Module):
    """Φ_score: Conv1d(d→W, kernel) + GELU → Linear → + PE → encoder layers → LN → Linear(W→1)."""

    def __init__(self, cfg: TokenizerConfig):
        super().__init__()
        self.conv = nn.Conv1d(cfg.dim, cfg.width, cfg.conv_kernel, padding=cfg.conv_kernel // 2)
        self.proj = nn.Linear(cfg.width, cfg.width)
        self.learned_pe = (nn.Parameter(torch.randn(cfg.window, cfg.width) * 0.02)
                           if cfg.scorer_pe == "learned" else None)
        self.layers = EncoderStack(cfg.scorer_layers, cfg.width, cfg.heads, cfg.ffn, cfg.dropout)
        self.norm = nn.LayerNorm(cfg.width)
        self.per_channel = cfg.per_channel
        self.head = nn.Linear(cfg.width, cfg.dim if cfg.per_channel else 1)

    def forward(self, m: torch.Tensor) -> torch.Tensor:
        """Logits (B, T), or (B, T, d) with per-channel allocation."""
        x = nn.functional.gelu(self.conv(m.transpose(1, 2))).transpose(1, 2)
        pe = self.learned_pe if self.learned_pe is not None else positions(m.shape[1], x.shape[-1], device=m.device)
        x = self.layers(self.proj(x) + pe)
        s = self.head(self.norm(x))
        return s if self.per_channel else s.squeeze(-1)


class SFMSTokenizer(nn.Module):
    """Scorer, keyframe encoder, quantiser and inpainter; buffers hold the motion normalisation."""

    def __init__(self, cfg: TokenizerConfig):
        super().__init__()
        self.cfg = cfg
        w, p = cfg.width, cfg.pe_dim
        stack = dict(width=w, heads=cfg.heads, ffn=cfg.ffn, dropout=cfg.dropout)
        self.scorer = KeyframeScorer(cfg)
        self.per_channel = cfg.per_channel
        self.embed = nn.Linear(1 if cfg.per_channel else cfg.dim, w)  # per channel: one value per token
        if cfg.per_channel:
            self.channel_embed = nn.Embedding(cfg.dim, w)
            self.memory_channel = nn.Embedding(cfg.dim, w)
        self.embed_pe = nn.Linear(w + p, w)
        self.keyframe_sink = nn.Parameter(torch.randn(w) * 0.02)
        self.keyframe_encoder = EncoderStack(cfg.keyframe_layers, **stack)
        self.quantizer = (FSQ(cfg.fsq_levels, w) if cfg.quantizer == "fsq"
                          else VQ(cfg.vq_codes, w, cfg.vq_codebook_weight, cfg.vq_commit_weight))
        self.memory_in = nn.Linear(w + p, w)
        self.memory_sink = nn.Parameter(torch.randn(w) * 0.02)
        self.blank = nn.Parameter(torch.randn(w) * 0.02)
        self.query_in = nn.Linear(w + p, w)
        self.transition_encoder = CrossStack(cfg.transition_layers, **stack)
        self.decoder_in = nn.Linear(w + p + 1, w)
        self.decoder = CrossStack(cfg.decoder_layers, **stack)
        self.out_norm = nn.LayerNorm(w)
        self.out = nn.Linear(w, cfg.dim)
        self.register_buffer("motion_mean", torch.zeros(cfg.dim))
        self.register_buffer("motion_std", torch.ones(cfg.dim))
        self.register_buffer("tau", torch.tensor(float(cfg.tau_start)))

    # --- parameter groups of the two optimisers ---------------------------------------------------
    def scorer_parameters(self) -> list[nn.Parameter]:
        return list(self.scorer.parameters())

    def main_parameters(self) -> list[nn.Parameter]:
        ids = {id(p) for p in self.scorer.parameters()}
        return [p for p in self.parameters() if id(p) not in ids]

    # --- normalisation ----------------------------------------------------------------------------
    def normalise(self, motion: torch.Tensor) -> torch.Tensor:
        return (motion - self.motion_mean) / self.motion_std

    def denormalise(self, motion: torch.Tensor) -> torch.Tensor:
        return motion * self.motion_std + self.motion_mean

    # --- pieces -----------------------------------------------------------------------------------
    def _pe(self, batch: int, device: torch.device) -> torch.Tensor:
        return positions(self.cfg.window, self.cfg.pe_dim, device=device).expand(batch, -1, -1)

    def encode_keyframes(self, m: torch.Tensor, hard: torch.Tensor) -> torch.Tensor:
        """Latents z^kf (B, T, W); attention mixes keyframes only (plus the sink slot)."""
        pe = self._pe(m.shape[0], m.device)
        h = self.embed_pe(torch.cat([self.embed(m), pe], dim=-1))
        x, pad = with_sink(h, self.keyframe_sink, hard < 0.5)
        return self.keyframe_encoder(x, pad)[:, 1:]

    def quantize(self, z: torch.Tensor, hard: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        return self.quantizer(z, hard)

    def inpaint(self, zq: torch.Tensor, hard: torch.Tensor, r: torch.Tensor) -> torch.Tensor:
        """m̂ (B, T, d) from quantised keyframe latents ``zq`` at ``hard`` positions (ST mask ``r``)."""
        b = zq.shape[0]
        pe = self._pe(b, zq.device)
        r3 = r[..., None]
        memory, memory_pad = with_sink(self.memory_in(torch.cat([r3 * zq, pe], dim=-1)), self.memory_sink, hard < 0.5)
        z_tf = self._transitions(memory, memory_pad, pe)
        u = r3 * zq + (1.0 - r3) * z_tf
        return self._frames(u, pe, r3, memory, memory_pad)

    def _transitions(self, memory: torch.Tensor, memory_pad: torch.Tensor, pe: torch.Tensor) -> torch.Tensor:
        """z_tf (B, T, W): blank ⊕ PE queries through the transition encoder (cross-attention to memory)."""
        queries = self.query_in(torch.cat([self.blank.expand(pe.shape[0], self.cfg.window, -1), pe], dim=-1))
        return self.transition_encoder(queries, memory, memory_pad)

    def _frames(self, u: torch.Tensor, pe: torch.Tensor, flag: torch.Tensor, memory: torch.Tensor,
                memory_pad: torch.Tensor) -> torch.Tensor:
        x = self.decoder(self.decoder_in(torch.cat([u, pe, flag], dim=-1)), memory, memory_pad)
        return self.out(self.out_norm(x))

    # --- per-channel allocation (channel_tokens) --------------------------------------------------
    def encode_channel_keyframes(self, m: torch.Tensor, flat: torch.Tensor, frames: torch.Tensor,
                                 chans: torch.Tensor, pad: torch.Tensor) -> torch.Tensor:
        """Latents (B, L, W) of the keyframe tokens (value of m at (frame, channel)); attention mixes
        the tokens of all channels (plus the sink slot), never a transition value."""
        values = m.reshape(m.shape[0], -1).gather(1, flat)[..., None]
        pe = positions(self.cfg.window, self.cfg.pe_dim, device=m.device)[frames]
        h = self.embed_pe(torch.cat([self.embed(values) + self.channel_embed(chans), pe], dim=-1))
        x, key_pad = with_sink(h, self.keyframe_sink, pad)
        return self.keyframe_encoder(x, key_pad)[:, 1:]

    def inpaint_channels(self, zq: torch.Tensor, r_tok: torch.Tensor, frames: torch.Tensor, chans: torch.Tensor,
                         pad: torch.Tensor, density: torch.Tensor) -> torch.Tensor:
        """m̂ (B, T, d) from quantised token latents ``zq`` (B, L, W) with ST values ``r_tok`` (B, L);
        ``density`` (B, T) is the fraction of channels keyed per frame (the decoder's keyframe flag)."""
        tok_pe = positions(self.cfg.window, self.cfg.pe_dim, device=zq.device)[frames]
        memory = self.memory_in(torch.cat([r_tok[..., None] * zq, tok_pe], dim=-1)) + self.memory_channel(chans)
        memory, memory_pad = with_sink(memory, self.memory_sink, pad)
        pe = self._pe(zq.shape[0], zq.device)
        z_tf = self._transitions(memory, memory_pad, pe)
        return self._frames(z_tf, pe, density[..., None], memory, memory_pad)

    def reconstruct_with(self, m: torch.Tensor, hard: torch.Tensor, r: torch.Tensor
                         ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """(m̂, code indices of the keyframes (N,), quantisation loss) of windows m for a given keyframe
        mask ``hard`` and straight-through mask ``r`` ((B, T), or (B, T, d) per channel)."""
        if not self.per_channel:
            zq, idx, q_loss = self.quantize(self.encode_keyframes(m, hard), hard)
            return self.inpaint(zq, hard, r), idx[hard > 0.5], q_loss
        flat, frames, chans, pad = gather_tokens(hard)
        keep = (~pad).float()
        zq, idx, q_loss = self.quantize(self.encode_channel_keyframes(m, flat, frames, chans, pad), keep)
        r_tok = r.reshape(r.shape[0], -1).gather(1, flat) * keep
        return self.inpaint_channels(zq, r_tok, frames, chans, pad, r.mean(-1)), idx[~pad], q_loss

    def allocate(self, fn, logits: torch.Tensor, *args, **kwargs):
        """Keyframe allocation: apply a per-row top-k function of :mod:`models.sfms.topk` (Algorithm 1,
        the hard top-k, the relaxation) to shared (B, T) logits, or independently to every channel
        column of (B, T, d) logits (per-channel: k keyframes per channel); results keep the logits' shape."""
        if not self.per_channel:
            return fn(logits, *args, **kwargs)
        out = fn(to_rows(logits), *args, **kwargs)
        d = self.cfg.dim
        return tuple(from_rows(x, d) for x in out) if isinstance(out, tuple) else from_rows(out, d)

    def fixed_mask(self, batch: int, device: torch.device) -> torch.Tensor | None:
        """The mask of the static / dense arms ((B, T, d) per channel, the same for every channel);
        None for dynamic keyframes."""
        if self.cfg.keyframe_mode == "static":
            mask = static_mask(batch, self.cfg.window, self.cfg.keyframes, device)
        elif self.cfg.keyframe_mode == "dense":
            mask = dense_mask(batch, self.cfg.window, device)
        else:
            return None
        return mask[..., None].expand(-1, -1, self.cfg.dim).contiguous() if self.per_channel else mask

    def select(self, m: torch.Tensor) -> torch.Tensor:
        """Deterministic keyframe mask (B, T), or (B, T, d) per channel: top-k of the scores (ties →
        lower index), with non-maximum suppression when ``suppression_radius`` > 0."""
        fixed = self.fixed_mask(m.shape[0], m.device)
        if fixed is not None:
            return fixed
        return self.allocate(hard_topk, self.scorer(m), self.cfg.keyframes, self.cfg.suppression_radius)

    # --- public API -------------------------------------------------------------------------------
    def _check(self, m: torch.Tensor) -> None:
        if m.ndim != 3 or m.shape[1:] != (self.cfg.window, self.cfg.dim):
            raise ValueError(f"motion windows must be (B, {self.cfg.window}, {self.cfg.dim}), got {tuple(m.shape)}")

    def encode(self, m: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """(classes (B, T) long, keyframe mask (B, T) bool, code indices (B, T) long; −1 off keyframes);
        each (B, T, d) with per-channel allocation."""
        self._check(m)
        hard = self.select(m)
        if self.per_channel:
            flat, frames, chans, pad = gather_tokens(hard)
            _, idx, _ = self.quantize(self.encode_channel_keyframes(m, flat, frames, chans, pad), (~pad).float())
            codes = scatter_tokens(idx, flat, pad, tuple(hard.shape), fill=-1)
            return codes + 1, hard > 0.5, codes
        zq, idx, _ = self.quantize(self.encode_keyframes(m, hard), hard)
        mask = hard > 0.5
        codes = torch.where(mask, idx, torch.full_like(idx, -1))
        return torch.where(mask, idx + 1, torch.zeros_like(idx)), mask, codes

    def decode(self, classes: torch.Tensor) -> torch.Tensor:
        """m̂ (B, T, d) from classes (B, T) (or (B, T, d) per channel); any number of keyframes from 0 to T."""
        hard = (classes > 0).float()
        if self.per_channel:
            flat, frames, chans, pad = gather_tokens(hard)
            keep = (~pad).float()
            tok = classes.reshape(classes.shape[0], -1).gather(1, flat)
            zq = self.quantizer.embed_indices((tok - 1).clamp(min=0)) * keep[..., None]
            return self.inpaint_channels(zq, keep, frames, chans, pad, hard.mean(-1))
        zq = self.quantizer.embed_indices((classes - 1).clamp(min=0)) * hard[..., None]
        return self.inpaint(zq, hard, hard)

    def reconstruct(self, m: torch.Tensor) -> torch.Tensor:
        return self.decode(self.encode(m)[0])

    # --- training ---------------------------------------------------------------------------------
    def forward(self, m: torch.Tensor, *, warmup: bool = False, dense_aux: float = 0.0,
                generator: torch.Generator | None = None) -> dict[str, torch.Tensor]:
        """Training losses of one batch (spec §2.8–2.9); ``loss`` is the total to back-propagate.

        Dynamic keyframes draw S Gumbel samples per window (zero logits, i.e. random k-subsets, while
        ``warmup``); the best-reconstructing sample is the target of the masking loss.
        """
        cfg = self.cfg
        self._check(m)
        b, t, _ = m.shape
        k = cfg.effective_keyframes
        logits = None
        fixed = self.fixed_mask(b, m.device)
        if fixed is None:
            samples = cfg.gumbel_samples
            logits = (m.new_zeros(b, t, *((cfg.dim,) if self.per_channel else ())) if warmup
                      else self.scorer(m))
            r, hard, _ = self.allocate(gumbel_soft_topk, logits.repeat_interleave(samples, 0), k, float(self.tau),
                                         generator=generator, eps=cfg.topk_eps, radius=cfg.suppression_radius)
        else:
            samples, r, hard = 1, fixed, fixed
        mm = m.repeat_interleave(samples, 0)
        rec, codes, q_loss = self.reconstruct_with(mm, hard, r)
        err_full = (rec - mm).pow(2)  # (B·S, T, d)
        err = err_full.mean(-1)  # (B·S, T)
        per_seq = err.detach().mean(-1).view(b, samples)
        best = per_seq.argmin(1)  # first minimum: ties go to the lowest sample
        rows = torch.arange(b, device=m.device) * samples + best
        err_kf = err_full if self.per_channel else err  # the keyframe loss is per keyed value
        err_used, hard_used = (err[rows], hard[rows]) if cfg.recon_on == "best" else (err, hard)
        kf_used = err_kf[rows] if cfg.recon_on == "best" else err_kf
        losses = {"motion": err_used.mean(),
                  "kf": (kf_used * hard_used).sum() / hard_used.sum().clamp(min=1.0),
                  "q": q_loss,
                  "mask": m.new_zeros(()),
                  "dense": m.new_zeros(())}
        if logits is not None and not warmup and cfg.mask_loss_weight > 0:
            p = self.allocate(relaxed_topk, logits, k, float(self.tau), cfg.topk_eps,
                                cfg.suppression_radius).clamp(0.0, 1.0)
            losses["mask"] = (p - hard[rows]).abs().mean()
        if dense_aux > 0:
            full = dense_mask(b, t, m.device)
            full = full[..., None].expand(-1, -1, cfg.dim).contiguous() if self.per_channel else full
            rec_d, _, q_d = self.reconstruct_with(m, full, full)
            losses["dense"] = (rec_d - m).pow(2).mean() + q_d
        losses["loss"] = (losses["motion"] + cfg.kf_loss_weight * losses["kf"] + losses["q"]
                          + cfg.mask_loss_weight * losses["mask"] + dense_aux * losses["dense"])
        losses["best_err"] = per_seq.min(1).values.mean()
        losses["mean_err"] = per_seq.mean()
        losses["codes"] = codes.detach()
        return losses
