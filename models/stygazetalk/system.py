"""The trained StyGazeTalk system: normalisers, frozen style encoder and generator in one module.

Everything inference needs is a buffer or parameter of :class:`StyGazeTalkSystem`, so one checkpoint
file restores it (``state_dict`` + the two configs). :meth:`StyGazeTalkSystem.next_block` produces the
N frames of one inference window (spec §2.10) from raw speech and the known motion track;
:meth:`StyGazeTalkSystem.next_blocks` produces the windows of several streams together (batched streaming),
each row as :meth:`~StyGazeTalkSystem.next_block` gives it alone, its draws from its own stream's generator.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import torch
from torch import nn

from dyadbench.seeding import derive_seed

from models.stygazetalk.audio import HOP, feature_dim, raw_features
from models.stygazetalk.config import MOTION_DIM, GeneratorConfig, StyleEncoderConfig
from models.stygazetalk.generator import MotionGenerator
from models.stygazetalk.normalise import ZScore
from models.stygazetalk.style_encoder import StyleEncoder

RESIDUAL_POOL = 4096  # residual vectors kept for sampled decoding


class StyGazeTalkSystem(nn.Module):
    def __init__(self, cfg: GeneratorConfig, se_cfg: StyleEncoderConfig | None):
        super().__init__()
        if cfg.style and (se_cfg is None or se_cfg.d_s != cfg.d_s or se_cfg.window != cfg.window):
            raise ValueError(f"{cfg.name} needs a style encoder with d_s={cfg.d_s} and window M={cfg.window}")
        self.cfg, self.se_cfg = cfg, se_cfg if cfg.style else None
        self.motion_norm = ZScore(MOTION_DIM)
        self.audio_norm = ZScore(feature_dim(cfg))
        with torch.random.fork_rng():  # initial weights depend on the config seed only
            torch.manual_seed(derive_seed("stygazetalk-init", cfg.seed))
            self.style_encoder = StyleEncoder(se_cfg) if cfg.style else None
            self.generator = MotionGenerator(cfg, feature_dim(cfg))
        # teacher-forced validation residuals (target − output, normalised units) for sampled decoding
        # (X1); fitted after training
        self.register_buffer("residual_pool", torch.zeros(RESIDUAL_POOL, MOTION_DIM))
        if self.style_encoder is not None and cfg.freeze_style_encoder:
            self.style_encoder.requires_grad_(False)

    def train(self, mode: bool = True) -> "StyGazeTalkSystem":
        super().train(mode)
        if self.style_encoder is not None and self.cfg.freeze_style_encoder:
            self.style_encoder.eval()  # D26: frozen, eval mode (no dropout) while the generator trains
        return self

    def audio_window(self, waveform: np.ndarray) -> np.ndarray:
        """Normalised window-local features (M, F) of one window's waveform (D12, D4)."""
        return self.audio_norm.np(raw_features(self.cfg, waveform))

    def style(self, window: torch.Tensor) -> torch.Tensor | None:
        """s = SE(window) for normalised motion windows (B, M, 7); None for the Base variant."""
        if self.style_encoder is None:
            return None
        return self.style_encoder(window)

    def drawer(self, rng: torch.Generator | None):
        """Sampled decoding (X1): output + a residual vector drawn uniformly from the validation pool
        (a residual bootstrap: heavy tails and cross-dim correlation kept). None for mean decoding."""
        if self.cfg.decoding == "mean":
            return None
        if rng is None:
            raise ValueError(f"{self.cfg.name} samples its frames: pass a seeded torch.Generator")
        pool = self.residual_pool * self.cfg.sample_temperature
        if self.cfg.sample_dims == "gaze":  # the head keeps its mean (smooth, speech-locked)
            pool = torch.cat([torch.zeros_like(pool[:, :3]), pool[:, 3:]], dim=1)

        def draw(mean: torch.Tensor) -> torch.Tensor:
            idx = torch.randint(pool.shape[0], mean.shape[:-1], generator=rng)
            return mean + pool[idx]

        return draw

    @torch.no_grad()
    def next_block(self, waveform: np.ndarray, recent: np.ndarray, style: torch.Tensor | None = None,
                   rng: torch.Generator | None = None) -> np.ndarray:
        """The N frames (N, 7) in degrees following ``recent``.

        - ``waveform``: the speech of frames u..u+M−1 (M·640 samples), u = t − W, t the first new frame.
        - ``recent``: the most recent known frames x_{..t−1} in degrees, at least M of them (seed or
          earlier outputs); the last W+1 are the warm-up motion inputs, the last M the style window.
        - ``style``: a fixed style vector (style transfer) instead of SE(last M frames).
        - ``rng``: the stream's generator for sampled decoding (X1); unused with mean decoding.
        """
        return self.next_blocks([waveform], [recent], style, [rng])[0]

    @torch.no_grad()
    def next_blocks(self, waveforms: Sequence[np.ndarray], recents: Sequence[np.ndarray],
                    style: torch.Tensor | None = None, rngs: Sequence[torch.Generator | None] | None = None
                    ) -> list[np.ndarray]:
        """:meth:`next_block` of B windows (one per stream) together: the N frames (N, 7) in degrees following
        each ``recents[b]``, ``waveforms[b]`` its speech, ``rngs[b]`` its stream's generator; ``style``: a fixed
        (1, d_s) style for every row. Each row is bit for bit what :meth:`next_block` gives it alone
        (:meth:`~models.stygazetalk.generator.MotionGenerator.generate_blocks`)."""
        cfg = self.cfg
        rngs = [None] * len(recents) if rngs is None else list(rngs)
        if not recents or not len(waveforms) == len(recents) == len(rngs):
            raise ValueError(f"next_blocks needs one waveform and one generator per motion track, got "
                             f"{len(waveforms)}, {len(rngs)} and {len(recents)}")
        for waveform, recent in zip(waveforms, recents):
            if recent.shape[0] < cfg.window or waveform.shape[0] != cfg.window * HOP:
                raise ValueError(f"next_block needs >= {cfg.window} known frames and {cfg.window * HOP} samples, "
                                 f"got {recent.shape[0]} frames and {waveform.shape[0]} samples")
        known = torch.from_numpy(np.stack([self.motion_norm.np(recent[-cfg.window:]) for recent in recents]))
        audio = torch.from_numpy(np.stack([self.audio_window(waveform) for waveform in waveforms]))
        s = style.expand(len(recents), -1) if style is not None else self.style(known)
        block = self.generator.generate_blocks(audio, known[:, -(cfg.warmup + 1):], s,
                                               [self.drawer(rng) for rng in rngs])
        return [self.motion_norm.np_inverse(row.numpy()) for row in block]

    @torch.no_grad()
    def reference_style(self, motion_deg: np.ndarray) -> torch.Tensor:
        """Style vector of a whole reference session: the mean of SE over its windows (length M, hop N)."""
        if self.style_encoder is None:
            raise ValueError(f"{self.cfg.name} has no style encoder; style transfer needs an SE variant")
        m, n = self.cfg.window, self.cfg.horizon
        if motion_deg.shape[0] < m:
            raise ValueError(f"a style reference needs at least M={m} frames, got {motion_deg.shape[0]}")
        norm = self.motion_norm.np(motion_deg)
        windows = np.stack([norm[s:s + m] for s in range(0, norm.shape[0] - m + 1, n)])
        return self.style_encoder(torch.from_numpy(windows)).mean(dim=0, keepdim=True)
