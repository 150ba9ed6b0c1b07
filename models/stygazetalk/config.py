"""StyGazeTalk configurations: every implementation decision of the spec (D1–D39) is a named field.

Two frozen dataclasses, :class:`StyleEncoderConfig` (stage 1, contrastive) and
:class:`GeneratorConfig` (stage 2, LSTM or Transformer generator), and a table of named presets:
the paper's variants (Base, SE-32, SE-64, SE-64-VEL, TFM-SE-64, MPGW-sim) at two sizes, ``base``
(the spec's decided sizes) and ``tiny`` (minutes on 2 CPU cores), plus ``se64-vel-x1``, an extension
beyond the paper (sampled eye decoding, X1) that the shipped checkpoint uses. A preset name is
``<size>-<variant>``, e.g. ``tiny-se64``; the style encoder presets are ``<size>-se32`` / ``<size>-se64``.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

from dyadbench.errors import ConfigError
from dyadbench.training.config import config_from_dict, config_to_dict  # noqa: F401  (config_from_dict re-exported)

MOTION_DIM = 7  # D1: [head_pitch, head_yaw, head_roll, L_pitch, L_yaw, R_pitch, R_yaw], degrees
CHECKPOINT_SELECTIONS = ("val-loss", "val-mse", "last")  # D27 and the two alternatives
STYLE_INPUTS = ("motion-window", "preceding", "past")  # D7 (literal) and the two windows that read no target
CHANNELS = ("head_pitch", "head_yaw", "head_roll", "left_pitch", "left_yaw", "right_pitch", "right_yaw")


def _require_fixed(config, fixed: dict) -> None:
    """Recorded decisions with no implemented alternative: each field must hold its only value."""
    for key, only in fixed.items():
        if getattr(config, key) != only:
            raise ConfigError(f"{config.name}: {key}={getattr(config, key)!r} is not implemented (only {only!r})")


@dataclass(frozen=True)
class StyleEncoderConfig:
    """Stage 1: Transformer style encoder trained with NT-Xent (spec §2.5, §2.8)."""

    name: str = "base-se64"
    d_s: int = 64  # D15: Transformer width = style dim (no output projection)
    layers: int = 4  # D16
    heads: int = 4
    ffn_mult: int = 4
    dropout: float = 0.1  # D14/D16 (0 in tiny)
    positional_encoding: str = "sinusoidal"  # D14: per-position sinusoidal "MTE" (not DiffPoseTalk's)
    pooling: str = "mean"  # D15
    window: int = 50  # SE window = generator window M (D31)
    temperature: float = 0.1  # D23
    loss_reduction: str = "mean"  # D22: mean over the 2B views (paper sums)
    pair_gap_max: int = 5  # D24: positive b starts M + U{0..gap} frames after a
    distinct_anchor_gap_s: float = 10.0  # D24: same-session anchors of one batch at least this far apart
    # D48 (ours): "adjacent" is D24 (the paper's positives); "same-speaker" pairs each anchor with a
    # non-overlapping window of the same speaker from any of the speaker's sessions (needs D46 "other-speakers")
    positives: str = "adjacent"
    # D46 (ours): which other windows of a batch are NT-Xent negatives. "all" is D24 as the paper allows
    # (same-speaker anchors, even from the speaker's other session, are negatives); "other-speakers" drops
    # same-speaker windows from the denominator, so the loss never pushes a speaker's sessions apart
    negatives: str = "all"
    # D47 (ours): what the projection reads of the normalised window. "angles" = the 7 z-scored angles
    # (D4/D15 as written); "centred" subtracts each window's per-channel mean, so windows cannot be matched
    # by a shared slow pose (head drift); "centred+velocity" also appends the 7 frame-to-frame differences
    # (0 at the first frame), Linear(14 -> d_s), so rates of saccades, glitches and noise are per-frame inputs
    input_features: str = "angles"
    batch_pairs: int = 32  # D25
    lr: float = 1e-4
    steps: int = 20_000
    normalisation: str = "zscore-train"  # D4
    angle_limit_deg: float = 40.0  # D3
    seed: int = 0

    def to_dict(self) -> dict:
        return config_to_dict(self)

    def validate(self) -> "StyleEncoderConfig":
        _require_fixed(self, {"positional_encoding": "sinusoidal", "pooling": "mean", "normalisation": "zscore-train"})
        if self.negatives not in ("all", "other-speakers"):
            raise ConfigError(f"{self.name}: negatives must be all or other-speakers, got {self.negatives!r}")
        if self.positives not in ("adjacent", "same-speaker"):
            raise ConfigError(f"{self.name}: positives must be adjacent or same-speaker, got {self.positives!r}")
        if self.positives == "same-speaker" and self.negatives != "other-speakers":
            raise ConfigError(f"{self.name}: same-speaker positives need negatives='other-speakers' (a speaker's "
                              f"other windows cannot be positives and negatives at once)")
        if self.input_features not in ("angles", "centred", "centred+velocity"):
            raise ConfigError(f"{self.name}: input_features must be angles, centred or centred+velocity, "
                              f"got {self.input_features!r}")
        if self.loss_reduction not in ("mean", "sum") or self.d_s % self.heads:
            raise ConfigError(f"{self.name}: loss_reduction must be mean or sum and heads must divide d_s")
        return self


@dataclass(frozen=True)
class GeneratorConfig:
    """Stage 2: speech-to-motion generator with sliding-window inference (spec §2.1–2.12)."""

    name: str = "base-se64"
    variant: str = "SE-64"  # the paper's row name (Table 2)
    # windows (D5, D31)
    window: int = 50  # M: LSTM steps per window
    horizon: int = 25  # N: new frames per window (one dyadbench turn)
    alignment: str = "one-frame-lag"  # D5: step i reads audio t+i and motion t+i-1, predicts t+i
    # audio (D10–D13)
    audio_features: str = "logmel"  # "logmel" (D13) | "wav2vec" (D10, local weights only)
    n_mels: int = 80  # D13 (40 in tiny)
    logmel_win_length: int = 1024  # D13
    wav2vec_path: str | None = None  # D10: local wav2vec2-base-960h folder; never downloaded
    wav2vec_finetune_top_k: int = 0  # D11: frozen
    window_local_audio: bool = True  # D12: features computed from the window's waveform only
    feature_grid_stride: int = 25  # D12: training windows start on this grid (N = the inference grid;
    # tiny uses 5 so that 16 short sessions give ~3,400 windows; any multiple of 1 keeps features window-local)
    # networks (D6, D14–D19, D29)
    d: int = 128  # D32: audio and motion projection width
    motion_encoder: str = "linear"  # D6
    style: bool = True  # False = Base (Z is 2d)
    d_s: int = 64
    # D7: SE reads the motion-input window (literal; covers M-1 targets in training, unlike inference);
    # "preceding": the M frames before it; "past" (leak-free, as at inference): the M frames just before the
    # first frame the loss scores (train_generator.style_window)
    style_input: str = "motion-window"
    freeze_style_encoder: bool = True  # D26
    backbone: str = "lstm"  # "lstm" | "transformer" (TFM, D29)
    lstm_layers: int = 3  # D17
    lstm_hidden: int = 256
    lstm_dropout: float = 0.1
    learned_initial_state: bool = True  # (h0, c0) parameters, reset every window [P §3.2]
    tfm_d_model: int = 192  # D29
    tfm_layers: int = 4
    tfm_heads: int = 4
    tfm_ffn: int = 768
    tfm_dropout: float = 0.1
    residual_output: bool = False  # D18: absolute (normalised) frame
    concat_order: tuple[str, ...] = ("audio", "motion", "style")  # D19
    # loss (D8, D9, D20, D21)
    lam: float = 1.0  # D21: L = lam * MSE + (1 - lam) * velocity MSE
    loss_outputs: str = "all"  # D8 ("last-n": only the last N outputs)
    loss_reduction: str = "mean"  # D20
    rollout_prob: float = 0.0  # D9
    # optimisation (D27)
    batch: int = 64
    lr: float = 5e-4
    lr_min: float = 1e-5
    lr_schedule: str = "cosine"
    steps: int = 30_000
    grad_clip: float = 1.0
    weight_decay: float = 0.0
    val_every: int = 500
    # D27: lowest validation L_gen; "val-mse": lowest validation L_mse (the same criterion whatever λ);
    # "last": the final weights
    checkpoint_selection: str = "val-loss"
    # data and evaluation (D3, D4, D28, D30)
    normalisation: str = "zscore-train"  # D4
    angle_limit_deg: float = 40.0  # D3: frames with any |angle| above are dropped by the adapter
    seed_window: str = "gt"  # D28: M ground-truth frames seed generation; "mpgw-sim" = D30
    # decoding (extension beyond the paper, X1): "mean" emits the regression output (the paper's
    # deterministic model); "sample" adds to each free-running output a residual vector drawn from the
    # teacher-forced validation residuals (residual bootstrap), seeded per stream
    decoding: str = "mean"
    sample_temperature: float = 1.0  # residual scale
    sample_dims: str = "gaze"  # "gaze": eye angles drawn, head decoded by its mean; "all"
    mpgw_bias_sd_deg: float = 4.0  # D30
    mpgw_noise_sd_deg: float = 2.0
    seed: int = 0

    @property
    def warmup(self) -> int:
        """W = M − N known steps before the N autoregressive ones (D5)."""
        return self.window - self.horizon

    @property
    def style_dim(self) -> int:
        return self.d_s if self.style else 0

    def to_dict(self) -> dict:
        return config_to_dict(self)

    def validate(self) -> "GeneratorConfig":
        if not 1 <= self.horizon <= self.window:
            raise ConfigError(f"{self.name}: need 1 <= horizon N <= window M, got N={self.horizon}, M={self.window}")
        if self.backbone not in ("lstm", "transformer"):
            raise ConfigError(f"{self.name}: backbone must be lstm or transformer, got {self.backbone!r}")
        if self.audio_features not in ("logmel", "wav2vec"):
            raise ConfigError(f"{self.name}: audio_features must be logmel or wav2vec")
        if self.style_input not in STYLE_INPUTS:
            raise ConfigError(f"{self.name}: style_input must be one of {', '.join(STYLE_INPUTS)}, "
                              f"got {self.style_input!r}")
        if self.loss_outputs not in ("all", "last-n"):
            raise ConfigError(f"{self.name}: loss_outputs must be all or last-n")
        if self.decoding not in ("mean", "sample") or self.sample_dims not in ("gaze", "all"):
            raise ConfigError(f"{self.name}: decoding must be mean or sample, sample_dims gaze or all")
        if self.seed_window not in ("gt", "mpgw-sim"):
            raise ConfigError(f"{self.name}: seed_window must be gt or mpgw-sim")
        _require_fixed(self, {"alignment": "one-frame-lag", "motion_encoder": "linear", "window_local_audio": True,
                              "normalisation": "zscore-train", "loss_reduction": "mean"})
        if self.checkpoint_selection not in CHECKPOINT_SELECTIONS:
            raise ConfigError(f"{self.name}: checkpoint_selection must be one of {', '.join(CHECKPOINT_SELECTIONS)}")
        if self.lr_schedule not in ("cosine", "constant"):
            raise ConfigError(f"{self.name}: lr_schedule must be cosine or constant")
        if sorted(self.concat_order) != ["audio", "motion", "style"]:
            raise ConfigError(f"{self.name}: concat_order must order audio, motion and style")
        if not self.sample_temperature >= 0.0:
            raise ConfigError(f"{self.name}: sample_temperature must be >= 0, got {self.sample_temperature}")
        if not 0.0 <= self.lam <= 1.0:
            raise ConfigError(f"{self.name}: lam must be in [0, 1], got {self.lam}")
        return self




# --- presets ----------------------------------------------------------------------------------------
_SE_BASE = StyleEncoderConfig(input_features="centred+velocity")
# spec §7.2, except: D47 centred angles + velocities (with the plain angles the encoder matched adjacent
# windows by their shared slow pose and retrieved speakers across sessions at chance), dropout 0.1 (as
# base; 0 overfitted the 16 training sessions) and 1,000 steps, chosen by cross-session retrieval val -> train
_SE_TINY = replace(_SE_BASE, layers=2, heads=2, dropout=0.1, lr=1e-3, steps=1000)

STYLE_ENCODERS: dict[str, StyleEncoderConfig] = {
    "base-se64": replace(_SE_BASE, name="base-se64"),
    "base-se32": replace(_SE_BASE, name="base-se32", d_s=32),
    "tiny-se64": replace(_SE_TINY, name="tiny-se64"),
    "tiny-se32": replace(_SE_TINY, name="tiny-se32", d_s=32),
}

_GEN_BASE = GeneratorConfig()
# spec §7.2 / §2.12 tiny column: d 32, LSTM 2x64, dropout 0, log-mel 40, Adam 2e-3 cosine -> 1e-4, batch 32
_GEN_TINY = replace(_GEN_BASE, n_mels=40, d=32, lstm_layers=2, lstm_hidden=64, lstm_dropout=0.0,
                    tfm_d_model=64, tfm_layers=2, tfm_heads=4, tfm_ffn=256, tfm_dropout=0.0,
                    batch=32, lr=2e-3, lr_min=1e-4, steps=1500, val_every=250, feature_grid_stride=5)

# variant -> (paper row, overrides). The style encoder each variant reads is named by STYLE_FOR.
_VARIANTS: dict[str, tuple[str, dict]] = {
    "base": ("Base", {"style": False}),
    "se32": ("SE-32", {"d_s": 32}),
    "se64": ("SE-64", {"d_s": 64}),
    "se64-vel": ("SE-64-VEL", {"d_s": 64, "lam": 0.5}),  # D21
    "tfm-se64": ("TFM-SE-64", {"d_s": 64, "backbone": "transformer"}),  # D29
    "mpgw-sim": ("MPGW-sim", {"d_s": 64, "seed_window": "mpgw-sim"}),  # D30 (same weights as SE-64)
    # extension beyond the paper (X1): SE-64-VEL trained alike, eye angles drawn from the residual
    # bootstrap at half scale (scale chosen on the val split among 0.25 / 0.5 / 0.75 / 1 by Sim_seq)
    "se64-vel-x1": ("SE-64-VEL + X1", {"d_s": 64, "lam": 0.5, "decoding": "sample", "sample_temperature": 0.5,
                                       "sample_dims": "gaze"}),
}

GENERATORS: dict[str, GeneratorConfig] = {}
for _size, _proto in (("base", _GEN_BASE), ("tiny", _GEN_TINY)):
    for _key, (_row, _over) in _VARIANTS.items():
        GENERATORS[f"{_size}-{_key}"] = replace(_proto, name=f"{_size}-{_key}", variant=_row, **_over).validate()


def style_encoder_for(gen: GeneratorConfig) -> str | None:
    """Name of the style-encoder preset a generator preset conditions on (None for Base)."""
    if not gen.style:
        return None
    size = gen.name.split("-", 1)[0]
    return f"{size}-se{gen.d_s}"


def get_style_config(name: str) -> StyleEncoderConfig:
    if name not in STYLE_ENCODERS:
        raise ConfigError(f"unknown style-encoder config {name!r} (known: {', '.join(STYLE_ENCODERS)})")
    return STYLE_ENCODERS[name]


def get_generator_config(name: str) -> GeneratorConfig:
    if name not in GENERATORS:
        raise ConfigError(f"unknown StyGazeTalk config {name!r} (known: {', '.join(GENERATORS)})")
    return GENERATORS[name]
