"""SFMS configurations: every numbered decision of the implementation spec is a named field.

Two dataclasses, :class:`TokenizerConfig` (stage 1) and :class:`PredictorConfig` (stage 2), and two
presets each: ``paper`` (window 48, width 256, the spec's layer counts; tokenizer ≈ 9.7 M parameters)
and ``tiny`` (width 64, one layer per stack; minutes on 2 CPU cores). Configs are frozen and are saved
as plain dicts in checkpoints and in results (``ModelInfo.config``).

Decision → field map (decision ids of the SFMS implementation spec, §6):

====  ============================================================================================
D1    ``mask_sharing``: "frame" = shared allocation (one keyframe mask for all channels; the shipped
      checkpoints, and every checkpoint saved before "channel" existed) | "channel" = per-channel
      allocation (each channel its own k keyframes, the paper's §V-B; :mod:`models.sfms.channel_tokens`)
D2    ``mask_loss_weight`` (α = 0.1; 0 = off), ``mask_target`` = "best_sample" (the best of S samples)
D3    ``kf_loss_weight`` (keyframe-focused reconstruction MSE, weight 1)
D4    ``warmup_frac`` (random placements, scorer frozen), ``dense_aux_weight``
D5    ``lr_main``, ``lr_scorer``, ``betas``, ``weight_decay``, ``scorer_update_every``
D6    ``tau_start``, ``tau_min``, ``tau_anneal_frac``
D7    ``gumbel_samples`` (S), ``recon_on`` ("all" | "best")
D8    ``scorer_layers``, ``keyframe_layers``, ``transition_layers``, ``decoder_layers``, ``heads``,
      ``ffn``, ``dropout``, ``conv_kernel``
D9    ``vq_codebook_weight``, ``vq_commit_weight``
D10   ``fsq_levels`` ([8, 6, 5] → 240 codes), ``pe_dim`` (concatenated positional encoding)
D11   ``keyframes`` (k = 7)
D12   ``PredictorConfig.tokenise`` = "window" (each 48-frame window tokenised on the fly)
D13   ``PredictorConfig.speaker_input`` = "continuous"
D14   ``PredictorConfig.speaker_span`` ("concurrent" = [t−40, t+8) | "past" = [t−40, t))
D15   ``PredictorConfig.keyframe_loss`` ("soft_dtw" | "bce"), ``sdtw_gamma``, ``sdtw_weight``
D16   ``PredictorConfig.class_weights`` = "group" (w₀ = 0.5/(1−ρ), w_kf = 0.5/ρ, ρ = k/T)
D17   ``PredictorConfig.sampling`` ("multinomial" | "greedy"), ``temperature``, ``top_k``
D18   ``PredictorConfig.keyframe_cap`` (None = off; k + 2 in the spec's option)
D22   ``normalisation`` = "zscore" (train-split mean/std per dim; MSE reported in z-space and raw) or
      "within-sequence" (train mean, pooled within-sequence std: head pose keeps its in-clip motion)
D24   ``PredictorConfig.neutral_prob`` (0.3), ``pre_start_prob`` (0.05); neutral = zero vector
D25   predictor layer counts (``speaker_layers`` … ``decoder_layers``)
D28   ``steps``, ``batch``, learning rates, ``lr_min``, ``warmup_frac``, ``grad_clip``
D30   ``PredictorConfig.emit`` = "last" (emit the last 8 frames of each decoded 48-window)
D31   ``scorer_pe`` ("sinusoidal" | "learned")
D32   ``suppression_radius`` (not in the paper; 0 = Algorithm 1 and top-k exactly as published): each
      soft and hard keyframe pick also suppresses its r neighbours on each side, so top-k of a
      temporally smooth score cannot pick adjacent frames
D33   ``PredictorConfig.speaker_audio`` (not in the paper): "speech" (the speaker's speech rows, every
      shipped flame56 checkpoint) | "none" (no audio branch: no audio encoder and no gated fusion; the
      speaker is its motion features alone). The REACT variant uses "none": the embedded corpus written in
      the REACT layout has no audio, and the paper's wav2vec2 features of the real REACT wavs are not
      available offline (REACT variant: :mod:`models.sfms.react`, decisions D19, D34, D35 there)
D34   (REACT variant, not a field) generated emotion frames mapped to REACT's ranges: AUs clipped to
      [0, 1], valence/arousal to [−1, 1], expression probabilities clipped at 0 and renormalised
      (:func:`models.sfms.react.to_valid_range`)
D35   (REACT variant, not a field) R = 10 reactions = R independent rollouts from a neutral past, reaction r
      of a sample sampled from a generator seeded ``derive_seed(seed, "sfms-react", speaker path, r)``
      (:func:`models.sfms.react.reaction_seed`)
====  ============================================================================================

Decisions that concern other datasets (D20/D21 L2L protocol and metric details, D23 per-host models,
D26/D27 naming and data statistics, D29 predecessor quirks) are not fields here: they belong to the
evaluation suites or were not implemented. D19 (REACT output space: the REACT variant models the 25-d
emotion features directly, no separate emotion head) is documented in :mod:`models.sfms.react`.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

from dyadbench.errors import ConfigError
from dyadbench.training.config import (BELOW_ONE, NON_NEGATIVE, POSITIVE, PROBABILITY, bounded,
                                       check_field_domains, check_field_types)
from dyadbench.training.config import config_from_dict as from_dict  # noqa: F401  (re-exported)
from dyadbench.training.config import config_to_dict as to_dict  # noqa: F401  (re-exported)

TOKENIZER_CHOICES = {
    "keyframe_mode": ("dynamic", "static", "dense"),
    "quantizer": ("fsq", "vq"),
    "mask_sharing": ("frame", "channel"),
    "mask_target": ("best_sample",),
    "recon_on": ("all", "best"),
    "scorer_pe": ("sinusoidal", "learned"),
    "normalisation": ("zscore", "within-sequence"),
}
PREDICTOR_CHOICES = {
    "tokenise": ("window",),
    "speaker_input": ("continuous",),
    "speaker_span": ("concurrent", "past"),
    "keyframe_loss": ("soft_dtw", "bce"),
    "class_weights": ("group",),
    "sampling": ("multinomial", "greedy"),
    "emit": ("last",),
    "speaker_audio": ("speech", "none"),
}


def _check_choices(cfg: Any, choices: dict[str, tuple[str, ...]]) -> None:
    check_field_types(cfg)
    check_field_domains(cfg)
    for name, allowed in choices.items():
        value = getattr(cfg, name)
        if value not in allowed:
            raise ConfigError(f"{type(cfg).__name__}.{name} = {value!r}; implemented: {', '.join(allowed)}")


@dataclass(frozen=True)
class TokenizerConfig:
    """Stage 1: keyframe scorer + Gumbel top-k + keyframe quantiser + inpainter (spec §2)."""

    dim: int = bounded(56, POSITIVE)  # motion dims d (layout-agnostic)
    window: int = bounded(48, POSITIVE)  # T
    width: int = bounded(256, POSITIVE)
    heads: int = bounded(8, POSITIVE)
    ffn: int = bounded(1024, POSITIVE)
    dropout: float = bounded(0.1, PROBABILITY)
    pe_dim: int = bounded(64, POSITIVE)  # D10: concatenated PE width
    conv_kernel: int = bounded(3, POSITIVE)  # D8
    scorer_layers: int = bounded(2, NON_NEGATIVE)  # D8
    keyframe_layers: int = bounded(3, NON_NEGATIVE)
    transition_layers: int = bounded(3, NON_NEGATIVE)
    decoder_layers: int = bounded(2, NON_NEGATIVE)
    scorer_pe: str = "sinusoidal"  # D31
    keyframes: int = bounded(7, POSITIVE)  # D11: k
    keyframe_mode: str = "dynamic"  # Table III arms: dynamic (learned top-k) | static (uniform) | dense
    mask_sharing: str = "frame"  # D1: "frame" (shared mask) | "channel" (per-channel allocation)
    quantizer: str = "fsq"  # fsq | vq
    fsq_levels: tuple[int, ...] = (8, 6, 5)  # D10
    vq_codes: int = bounded(256, POSITIVE)
    vq_codebook_weight: float = bounded(1.0, NON_NEGATIVE)  # D9
    vq_commit_weight: float = bounded(1.0, NON_NEGATIVE)  # D9
    topk_eps: float = bounded(1e-10, POSITIVE)
    suppression_radius: int = bounded(0, NON_NEGATIVE)  # D32: frames suppressed each side of a pick (0 = as published)
    gumbel_samples: int = bounded(4, POSITIVE)  # D7: S
    recon_on: str = "all"  # D7
    kf_loss_weight: float = bounded(1.0, NON_NEGATIVE)  # D3
    mask_loss_weight: float = bounded(0.1, NON_NEGATIVE)  # D2: α
    mask_target: str = "best_sample"  # D2
    warmup_frac: float = bounded(0.1, PROBABILITY)  # D4
    dense_aux_weight: float = bounded(0.0, NON_NEGATIVE)  # D4
    tau_start: float = bounded(1.0, POSITIVE)  # D6
    tau_min: float = bounded(0.3, POSITIVE)  # D6
    tau_anneal_frac: float = bounded(0.6, PROBABILITY)  # D6
    lr_main: float = bounded(2e-4, POSITIVE)  # D5
    lr_scorer: float = bounded(1e-4, POSITIVE)  # D5
    lr_min: float = bounded(1e-6, NON_NEGATIVE)
    betas: tuple[float, float] = bounded((0.9, 0.98), BELOW_ONE)
    weight_decay: float = bounded(0.01, NON_NEGATIVE)
    grad_clip: float = bounded(1.0, POSITIVE)
    scorer_update_every: int = bounded(1, POSITIVE)  # D5: 1 = both optimisers step every iteration
    steps: int = bounded(20_000, POSITIVE)  # D28
    batch: int = bounded(256, POSITIVE)
    val_every: int = bounded(500, POSITIVE)
    ema_decay: float = bounded(0.0, BELOW_ONE)  # EMA of the weights for validation and checkpoint (0 = off)
    normalisation: str = "zscore"  # D22

    def __post_init__(self) -> None:
        _check_choices(self, TOKENIZER_CHOICES)
        if self.keyframe_mode != "dense" and not 1 <= self.keyframes <= self.window:
            raise ConfigError(f"keyframes must be in 1..window ({self.window}), got {self.keyframes}")
        if self.width % self.heads:
            raise ConfigError(f"width {self.width} is not divisible by heads {self.heads}")
        if any(level < 2 for level in self.fsq_levels):
            raise ConfigError(f"FSQ levels must be >= 2, got {self.fsq_levels}")

    @property
    def n_codes(self) -> int:
        if self.quantizer == "fsq":
            n = 1
            for level in self.fsq_levels:
                n *= level
            return n
        return self.vq_codes

    @property
    def n_classes(self) -> int:
        """Per-frame classes: 0 = transition frame, 1 + code = keyframe."""
        return self.n_codes + 1

    @property
    def per_channel(self) -> bool:
        """Per-channel keyframe allocation (classes (B, T, d)) rather than one shared mask (classes (B, T))."""
        return self.mask_sharing == "channel"

    @property
    def effective_keyframes(self) -> int:
        return self.window if self.keyframe_mode == "dense" else self.keyframes


@dataclass(frozen=True)
class PredictorConfig:
    """Stage 2: listening-head predictor over per-frame classes (spec §3)."""

    past: int = bounded(40, POSITIVE)
    future: int = bounded(8, POSITIVE)
    width: int = bounded(256, POSITIVE)
    heads: int = bounded(8, POSITIVE)
    ffn: int = bounded(1024, POSITIVE)
    dropout: float = bounded(0.1, PROBABILITY)
    speaker_layers: int = bounded(2, NON_NEGATIVE)  # D25
    audio_layers: int = bounded(2, NON_NEGATIVE)
    fusion_blocks: int = bounded(2, NON_NEGATIVE)
    listener_layers: int = bounded(2, NON_NEGATIVE)
    context_layers: int = bounded(4, NON_NEGATIVE)
    decoder_layers: int = bounded(2, NON_NEGATIVE)
    audio_bins: int = bounded(128, POSITIVE)
    audio_rows_per_frame: int = bounded(4, POSITIVE)  # mel rows per motion frame (hop 10 ms at 25 fps)
    audio_window_s: float = bounded(0.025, POSITIVE)  # mel analysis window
    tokenise: str = "window"  # D12
    speaker_input: str = "continuous"  # D13
    speaker_span: str = "concurrent"  # D14
    keyframe_loss: str = "soft_dtw"  # D15
    sdtw_gamma: float = bounded(0.1, POSITIVE)  # D15
    sdtw_weight: float = bounded(1.0, NON_NEGATIVE)  # D15
    class_weights: str = "group"  # D16
    sampling: str = "multinomial"  # D17
    temperature: float = bounded(1.0, POSITIVE)  # D17
    top_k: int = bounded(0, NON_NEGATIVE)  # D17: 0 = off
    keyframe_cap: int | None = bounded(None, POSITIVE)  # D18
    neutral_prob: float = bounded(0.3, PROBABILITY)  # D24
    pre_start_prob: float = bounded(0.05, PROBABILITY)  # D24
    emit: str = "last"  # D30
    speaker_audio: str = "speech"  # D33: "speech" | "none" (no audio branch; the REACT variant)
    lr: float = bounded(3e-4, POSITIVE)  # D28
    lr_min: float = bounded(1e-6, NON_NEGATIVE)
    betas: tuple[float, float] = bounded((0.9, 0.98), BELOW_ONE)
    weight_decay: float = bounded(0.01, NON_NEGATIVE)
    warmup_frac: float = bounded(0.05, PROBABILITY)
    grad_clip: float = bounded(1.0, POSITIVE)
    steps: int = bounded(20_000, POSITIVE)
    batch: int = bounded(256, POSITIVE)
    ema_decay: float = bounded(0.0, BELOW_ONE)  # EMA of the weights for validation and checkpoint (0 = off)

    def __post_init__(self) -> None:
        _check_choices(self, PREDICTOR_CHOICES)
        if self.width % self.heads:
            raise ConfigError(f"width {self.width} is not divisible by heads {self.heads}")

    @property
    def window(self) -> int:
        return self.past + self.future


TOKENIZER_PRESETS: dict[str, TokenizerConfig] = {
    "paper": TokenizerConfig(),
    # tiny: the shipped tokenizer; keyframes, suppression and normalisation as measured in the README
    "tiny": TokenizerConfig(width=64, heads=4, ffn=128, pe_dim=16, scorer_layers=1, keyframe_layers=1,
                            transition_layers=1, decoder_layers=1, fsq_levels=(8, 6, 5), vq_codes=240,
                            keyframes=10, suppression_radius=2, normalisation="within-sequence",
                            gumbel_samples=2, steps=2000, batch=32, tau_min=0.5,
                            lr_main=2e-3, lr_scorer=1e-3, val_every=500),
}
PREDICTOR_PRESETS: dict[str, PredictorConfig] = {
    "paper": PredictorConfig(),
    "tiny": PredictorConfig(width=64, heads=4, ffn=128, speaker_layers=1, audio_layers=1, fusion_blocks=1,
                            listener_layers=1, context_layers=1, decoder_layers=1, audio_bins=32,
                            steps=300, batch=32, lr=1e-3),
}


def _preset(presets: dict, name: str, kind: str):
    try:
        return presets[name]
    except KeyError:
        raise ConfigError(f"unknown {kind} config {name!r} (known: {', '.join(presets)})") from None


def tokenizer_preset(name: str, **overrides: Any) -> TokenizerConfig:
    return replace(_preset(TOKENIZER_PRESETS, name, "tokenizer"), **overrides)


def predictor_preset(name: str, **overrides: Any) -> PredictorConfig:
    return replace(_preset(PREDICTOR_PRESETS, name, "predictor"), **overrides)
