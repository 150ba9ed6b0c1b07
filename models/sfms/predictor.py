"""Stage 2 of SFMS: the listening-head predictor over per-frame classes (spec §3).

Inputs of one step predicting listener frames [t, t+F): the listener's past classes (B, P), speaker
motion (B, P+F, d) and speaker log-mel rows (B, (P+F)·rows, bins) over [t−P, t+F), with a validity
mask (B, P+F) for frames outside the clip or not yet available (with ``speaker_audio = "none"``, D33, the
rows are ignored and no audio branch exists). Output: logits (B, F, V), V = codes + 1
(class 0 = transition frame). With a per-channel tokenizer (:mod:`models.sfms.channel_tokens`) the past
classes are (B, P, d) and the logits (B, F, d, V).
"""

from __future__ import annotations

import torch
from torch import nn

from models.sfms.channel_tokens import to_rows
from models.sfms.config import PredictorConfig
from models.sfms.layers import CrossStack, EncoderStack, positions
from models.sfms.soft_dtw import soft_dtw_divergence


def visible_pad(valid: torch.Tensor) -> torch.Tensor:
    """Key-padding mask (True = hidden) from validity; a row with no valid key sees all (zero) padding."""
    pad = ~valid
    return pad & ~pad.all(-1, keepdim=True)


class GatedFusionBlock(nn.Module):
    """x̃ = SelfAttn(LN x); x ← x + x̃ + α·CrossAttn(LN x̃, LN y); x ← x + FFN(LN x); α starts at 0."""

    def __init__(self, width: int, heads: int, ffn: int, dropout: float):
        super().__init__()
        self.norm_self = nn.LayerNorm(width)
        self.self_attn = nn.MultiheadAttention(width, heads, dropout=dropout, batch_first=True)
        self.norm_query = nn.LayerNorm(width)
        self.norm_audio = nn.LayerNorm(width)
        self.cross_attn = nn.MultiheadAttention(width, heads, dropout=dropout, batch_first=True)
        self.alpha = nn.Parameter(torch.zeros(()))
        self.norm_ffn = nn.LayerNorm(width)
        self.ffn = nn.Sequential(nn.Linear(width, ffn), nn.GELU(), nn.Dropout(dropout), nn.Linear(ffn, width),
                                 nn.Dropout(dropout))

    def forward(self, x: torch.Tensor, y: torch.Tensor, pad: torch.Tensor) -> torch.Tensor:
        h = self.norm_self(x)
        x_tilde = self.self_attn(h, h, h, key_padding_mask=pad, need_weights=False)[0]
        ya = self.norm_audio(y)
        cross = self.cross_attn(self.norm_query(x_tilde), ya, ya, key_padding_mask=pad, need_weights=False)[0]
        x = x + x_tilde + self.alpha * cross
        return x + self.ffn(self.norm_ffn(x))


class SFMSPredictor(nn.Module):
    """Speaker motion and audio encoders, gated fusion, listener encoder, context encoder, decoder."""

    def __init__(self, cfg: PredictorConfig, motion_dim: int, n_classes: int, per_channel: bool = False):
        super().__init__()
        self.cfg, self.n_classes = cfg, n_classes
        self.channels = motion_dim if per_channel else None  # classes per (frame, channel)
        tables = motion_dim if per_channel else 1
        w = cfg.width
        stack = dict(width=w, heads=cfg.heads, ffn=cfg.ffn, dropout=cfg.dropout)
        self.speaker_in = nn.Linear(motion_dim, w)
        self.speaker_encoder = EncoderStack(cfg.speaker_layers, **stack)
        self.hears = cfg.speaker_audio == "speech"  # D33: "none" builds no audio branch and no fusion
        if self.hears:
            self.audio_conv = nn.Conv1d(cfg.audio_bins, w, 3, padding=1)
            self.audio_pool = nn.MaxPool1d(cfg.audio_rows_per_frame)
            self.audio_encoder = EncoderStack(cfg.audio_layers, **stack)
        self.fusion = nn.ModuleList(GatedFusionBlock(w, cfg.heads, cfg.ffn, cfg.dropout)
                                    for _ in range(cfg.fusion_blocks if self.hears else 0))
        self.listener_embed = nn.Embedding(n_classes * tables, w)  # per channel: one table of V rows each
        self.listener_encoder = EncoderStack(cfg.listener_layers, **stack)
        self.segment = nn.Parameter(torch.randn(2, w) * 0.02)
        self.context_encoder = EncoderStack(cfg.context_layers, **stack)
        self.context_norm = nn.LayerNorm(w)
        self.queries = nn.Parameter(torch.randn(cfg.future, w) * 0.02)
        self.decoder = CrossStack(cfg.decoder_layers, **stack)
        self.out_norm = nn.LayerNorm(w)
        self.out = nn.Linear(w, n_classes * tables)
        self.register_buffer("audio_mean", torch.zeros(cfg.audio_bins))
        self.register_buffer("audio_std", torch.ones(cfg.audio_bins))

    def forward(self, past: torch.Tensor, speaker: torch.Tensor, audio: torch.Tensor,
                valid: torch.Tensor) -> torch.Tensor:
        cfg = self.cfg
        b, w, dev = past.shape[0], cfg.window, past.device
        if cfg.speaker_span == "past":
            valid = valid.clone()
            valid[:, cfg.past:] = False
        keep = valid[..., None].float()
        rows = audio * valid.repeat_interleave(cfg.audio_rows_per_frame, 1)[..., None].float()
        pad = visible_pad(valid)
        pe = positions(w, cfg.width, device=dev)
        x = self.speaker_encoder(self.speaker_in(speaker * keep) + pe, pad)
        if self.hears:
            y = self.audio_pool(nn.functional.gelu(self.audio_conv(rows.transpose(1, 2)))).transpose(1, 2)
            y = self.audio_encoder(y + pe, pad)
            for block in self.fusion:
                x = block(x, y, pad)
        z_l = self.listener_encoder(self._embed_past(past) + pe[: cfg.past])
        context = torch.cat([z_l + self.segment[0], x + self.segment[1]], dim=1)
        context_pad = torch.cat([torch.zeros(b, cfg.past, dtype=torch.bool, device=dev), pad], dim=1)
        memory = self.context_norm(self.context_encoder(context, context_pad))
        q = (self.queries + positions(cfg.future, cfg.width, start=cfg.past, device=dev)).expand(b, -1, -1)
        logits = self.out(self.out_norm(self.decoder(q, memory, context_pad)))
        return logits if self.channels is None else logits.view(b, cfg.future, self.channels, self.n_classes)

    def _embed_past(self, past: torch.Tensor) -> torch.Tensor:
        """(B, P, W): the class embedding, or per channel the mean of the d channels' embeddings."""
        if self.channels is None:
            return self.listener_embed(past)
        offsets = torch.arange(self.channels, device=past.device) * self.n_classes
        return self.listener_embed(past + offsets).mean(2)


def class_weights(n_classes: int, keyframes: int, window: int) -> torch.Tensor:
    """D16 group weights: w₀ = 0.5/(1−ρ) for transitions, 0.5/ρ for every keyframe class, ρ = k/T."""
    rho = keyframes / window
    w = torch.full((n_classes,), 0.5 / rho)
    w[0] = 0.5 / (1.0 - rho)
    return w


def predictor_losses(logits: torch.Tensor, targets: torch.Tensor, weights: torch.Tensor,
                     cfg: PredictorConfig) -> dict[str, torch.Tensor]:
    """Weighted CE (eq. 14: Σ w·NLL / token count) + λ·keyframe-timing term (soft-DTW divergence or BCE).

    ``logits`` (B, F, V) with ``targets`` (B, F), or per channel (B, F, d, V) with (B, F, d): the CE runs
    over every (frame, channel) token and the timing term over each channel's F-frame sequence.
    """
    logp = torch.log_softmax(logits, dim=-1)
    nll = -logp.gather(-1, targets[..., None]).squeeze(-1)
    ce = (weights[targets] * nll).sum() / targets.numel()
    p_kf = (1.0 - logp[..., 0].exp()).clamp(1e-6, 1 - 1e-6)
    is_kf = (targets != 0).float()
    if targets.ndim == 3:
        p_kf, is_kf = to_rows(p_kf), to_rows(is_kf)
    if cfg.keyframe_loss == "soft_dtw":
        timing = soft_dtw_divergence(p_kf, is_kf, cfg.sdtw_gamma).mean()
    else:
        timing = nn.functional.binary_cross_entropy(p_kf, is_kf)
    return {"loss": ce + cfg.sdtw_weight * timing, "ce": ce, "timing": timing}
