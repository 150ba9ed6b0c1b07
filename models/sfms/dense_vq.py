"""Dense VQ-VAE motion tokenizer in the Learning2Listen style: the "L2L" / "Dense-VQ" baseline of SFMS
Table IV (paper §V-B: "group-based discrete tokenization"; spec §2.12: groups of 8 frames, one VQ code each).

Every group of ``downsample`` frames becomes one token: a linear patch embedding (Conv1d with kernel =
stride = ``downsample``, i.e. a linear map of the group's frames) plus a learned position, the encoder
stack, nearest-code vector quantisation (:class:`models.sfms.vq.VQ`, straight-through, codebook and
commitment loss), plus a learned position, the decoder stack, and the transposed patch map back to
``downsample`` frames. ``downsample`` = 1 is a per-frame VQ tokenizer. No keyframes: every window carries
T / ``downsample`` codes.

Decisions where L2L's own VQ-VAE differs (it is a deeper convolution + transformer stack of width 256 with
a 200-code codebook): the patch maps here are linear and all nonlinearity is in the transformer stacks, so
the widths, layer counts, codebook and optimiser come from the same :class:`TokenizerConfig` as the SFMS
arms it is compared with (``keyframe_layers`` encoder layers, ``decoder_layers`` decoder layers,
``vq_codes`` codes); with zero layers the model is linear map → VQ → linear map, which the tests use for
an exact-reconstruction case.

The class has the training interface of :class:`models.sfms.tokenizer.SFMSTokenizer` that
:func:`models.sfms.train_tokenizer.fit_tokenizer` uses (``forward`` losses, ``reconstruct``,
``main_parameters`` / ``scorer_parameters``, normalisation buffers, ``tau``), so both train in one loop.
"""

from __future__ import annotations

import torch
from torch import nn

from models.sfms.config import TokenizerConfig
from models.sfms.layers import EncoderStack
from models.sfms.vq import VQ


class DenseVQVAE(nn.Module):
    """Patch embedding → encoder → VQ per group of ``downsample`` frames → decoder → transposed patch map."""

    def __init__(self, cfg: TokenizerConfig, downsample: int = 8):
        super().__init__()
        if downsample < 1 or cfg.window % downsample:
            raise ValueError(f"downsample must divide the window ({cfg.window}), got {downsample}")
        if cfg.quantizer != "vq":
            raise ValueError(f"the dense VQ-VAE quantises with a VQ codebook; config has quantizer={cfg.quantizer!r}")
        self.cfg = cfg
        self.downsample = downsample
        self.tokens = cfg.window // downsample
        w = cfg.width
        stack = dict(width=w, heads=cfg.heads, ffn=cfg.ffn, dropout=cfg.dropout)
        self.patch = nn.Conv1d(cfg.dim, w, downsample, stride=downsample)
        self.encoder_pe = nn.Parameter(torch.randn(self.tokens, w) * 0.02)
        self.encoder = EncoderStack(cfg.keyframe_layers, **stack)
        self.quantizer = VQ(cfg.vq_codes, w, cfg.vq_codebook_weight, cfg.vq_commit_weight)
        self.decoder_pe = nn.Parameter(torch.randn(self.tokens, w) * 0.02)
        self.decoder = EncoderStack(cfg.decoder_layers, **stack)
        self.unpatch = nn.ConvTranspose1d(w, cfg.dim, downsample, stride=downsample)
        self.register_buffer("motion_mean", torch.zeros(cfg.dim))
        self.register_buffer("motion_std", torch.ones(cfg.dim))
        self.register_buffer("tau", torch.tensor(float(cfg.tau_start)))  # unused; fit_tokenizer anneals it

    @property
    def n_codes(self) -> int:
        return self.quantizer.n_codes

    def main_parameters(self) -> list[nn.Parameter]:
        return list(self.parameters())

    def scorer_parameters(self) -> list[nn.Parameter]:
        """No keyframe scorer: the second optimiser of the SFMS loop has nothing to train."""
        return []

    def normalise(self, motion: torch.Tensor) -> torch.Tensor:
        return (motion - self.motion_mean) / self.motion_std

    def denormalise(self, motion: torch.Tensor) -> torch.Tensor:
        return motion * self.motion_std + self.motion_mean

    def _check(self, m: torch.Tensor) -> None:
        if m.ndim != 3 or m.shape[1:] != (self.cfg.window, self.cfg.dim):
            raise ValueError(f"motion windows must be (B, {self.cfg.window}, {self.cfg.dim}), got {tuple(m.shape)}")

    def latents(self, m: torch.Tensor) -> torch.Tensor:
        """Pre-quantisation latents (B, T / downsample, W) of windows m (B, T, d)."""
        self._check(m)
        return self.encoder(self.patch(m.transpose(1, 2)).transpose(1, 2) + self.encoder_pe)

    def render(self, zq: torch.Tensor) -> torch.Tensor:
        """m̂ (B, T, d) from quantised latents (B, T / downsample, W)."""
        return self.unpatch(self.decoder(zq + self.decoder_pe).transpose(1, 2)).transpose(1, 2)

    def encode(self, m: torch.Tensor) -> torch.Tensor:
        """Code indices (B, T / downsample) long."""
        return self.quantizer.nearest(self.latents(m))

    def decode(self, codes: torch.Tensor) -> torch.Tensor:
        """m̂ (B, T, d) from code indices (B, T / downsample)."""
        if codes.ndim != 2 or codes.shape[1] != self.tokens:
            raise ValueError(f"codes must be (B, {self.tokens}), got {tuple(codes.shape)}")
        return self.render(self.quantizer.embed_indices(codes))

    def reconstruct(self, m: torch.Tensor) -> torch.Tensor:
        return self.decode(self.encode(m))

    def forward(self, m: torch.Tensor, *, warmup: bool = False, dense_aux: float = 0.0,
                generator: torch.Generator | None = None) -> dict[str, torch.Tensor]:
        """Training losses of one batch: motion MSE + VQ codebook/commitment loss (``loss`` is their sum).
        ``warmup``, ``dense_aux`` and ``generator`` belong to the SFMS loop and have no effect here."""
        zq, codes, q_loss = self.quantizer(self.latents(m))
        motion = (self.render(zq) - m).pow(2).mean()
        return {"motion": motion, "q": q_loss, "loss": motion + q_loss, "codes": codes.detach()}
