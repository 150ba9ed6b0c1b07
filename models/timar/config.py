"""TIMAR configurations: the paper's sizes (base, large, huge) and a CPU-trainable ``tiny``.

One :class:`TimarConfig` describes both model variants:

- ``variant = "faithful"``: learned absolute positions indexed inside the current window
  (``max_turns`` turns of ``tokens_per_turn`` tokens), turn-level causal attention (a token attends
  to every token of its own and earlier turns of the window), as in the released implementation.
- ``variant = "stream"``: learned positions inside a turn, a relative encoding of turn distance (a
  learned key offset per layer and distance 0..``max_turns``-1: score = q·(k + r_d)), and a per-turn
  sliding band (a turn attends to itself and the ``band`` turns before it). Nothing depends on where
  the window starts, so past keys/values never change.

``motion_norm`` records a deliberate choice about the motion the model sees and predicts:

- ``"none"``: raw motion, as in the released implementation (the paper's sizes keep it).
- ``"per_dim"``: every one of the 56 dimensions is standardised with the mean and standard deviation
  of the training motion (both participants, every frame; std floored at ``MOTION_STD_FLOOR``) for the
  motion tokens (user and agent) and the diffusion target; samples are mapped back, so predictions
  stay in the original units. The statistics are buffers of the model and travel in the checkpoint.
  Raw FLAME jaw and head-rotation dimensions have standard deviations of 0.01–0.05 against ~0.2–1.4
  for expression, so unnormalised they are buried under the unit-variance diffusion noise and barely
  weigh on the training loss; ``tiny`` therefore uses ``"per_dim"`` (a deviation from the release).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

from dyadbench.errors import ConfigError
from dyadbench.training.config import config_from_dict, config_to_dict

NUM_SPECIAL_TOKENS = 10
MOTION_DIM = 56
SPEECH_DIMS = {"logmel": 40, "wav2vec": 1024}
VARIANTS = ("faithful", "stream")
MOTION_NORMS = ("none", "per_dim")
MOTION_STD_FLOOR = 1e-3  # per-dim std floor of "per_dim" normalisation (a constant training dim stays finite)


@dataclass(frozen=True)
class TimarConfig:
    name: str = "tiny"
    variant: str = "faithful"
    # tokens
    token_dim: int = 64  # d_t: shared token space of speech and motion tokens
    speech_frontend: str = "logmel"  # "logmel" (embedded default) or "wav2vec" (local weights)
    speech_width: int | None = None  # speech feature width when not the frontend's usual (a smaller wav2vec)
    motion_dim: int = MOTION_DIM
    frames_per_turn: int = 25  # 1-s turns at 25 fps
    samples_per_turn: int = 16_000  # 1-s turns at 16 kHz
    max_turns: int = 8  # turns per training clip = history n (7) + the current turn
    motion_norm: str = "none"  # "none" (released: raw motion) or "per_dim" (train mean/std, see module doc)
    # backbone
    dim: int = 64  # D
    heads: int = 4
    depth: int = 3
    mlp_ratio: float = 4.0
    dropout: float = 0.0  # projections and MLPs (0.1 in the release)
    attn_dropout: float = 0.0  # attention probabilities (0.1 in the release; 0 keeps tiny fast on a CPU)
    # diffusion head
    head_width: int = 128
    head_blocks: int = 3
    train_steps: int = 1000
    sampling_steps: int = 5
    diffusion_batch_mul: int = 4
    # training recipe
    mask_ratio_mean: float = 1.0
    mask_ratio_std: float = 0.25
    mask_ratio_min: float = 0.7
    cfg_dropout: float = 0.1
    lr: float = 1e-4
    weight_decay: float = 0.02
    grad_clip: float = 3.0
    ema_decay: float = 0.9999
    batch_size: int = 32

    def __post_init__(self) -> None:
        if self.variant not in VARIANTS:
            raise ConfigError(f"TIMAR variant must be one of {VARIANTS}, got {self.variant!r}")
        if self.speech_frontend not in SPEECH_DIMS:
            raise ConfigError(f"speech frontend must be one of {sorted(SPEECH_DIMS)}, got {self.speech_frontend!r}")
        if self.motion_norm not in MOTION_NORMS:
            raise ConfigError(f"motion_norm must be one of {MOTION_NORMS}, got {self.motion_norm!r}")
        if self.dim % self.heads:
            raise ConfigError(f"dim {self.dim} is not divisible by heads {self.heads}")

    @property
    def speech_dim(self) -> int:
        return self.speech_width or SPEECH_DIMS[self.speech_frontend]

    @property
    def tokens_per_turn(self) -> int:
        """4 modality segments of ``frames_per_turn`` tokens plus the 10 special tokens."""
        return 4 * self.frames_per_turn + NUM_SPECIAL_TOKENS

    @property
    def max_context(self) -> int:
        """Largest history n the model supports (window = n + 1 turns, or a band of n turns)."""
        return self.max_turns - 1

    def to_dict(self) -> dict:
        return config_to_dict(self)

    @classmethod
    def from_dict(cls, data: dict) -> "TimarConfig":
        return config_from_dict(cls, data)


PRESETS: dict[str, TimarConfig] = {
    # trainable on a 2-core CPU in minutes: log-mel speech, no dropout, higher lr and faster EMA (short runs),
    # per-dimension motion normalisation
    "tiny": TimarConfig(batch_size=8, lr=1e-3, ema_decay=0.999, motion_norm="per_dim"),
    # the paper's sizes (wav2vec 2.0 frontend, d_t = 1024, diffusion head 3 x 1024)
    "base": TimarConfig(name="base", token_dim=1024, speech_frontend="wav2vec", dim=768, heads=12, depth=24,
                        head_width=1024, dropout=0.1, attn_dropout=0.1),
    "large": TimarConfig(name="large", token_dim=1024, speech_frontend="wav2vec", dim=1024, heads=16, depth=32,
                         head_width=1024, dropout=0.1, attn_dropout=0.1),
    "huge": TimarConfig(name="huge", token_dim=1024, speech_frontend="wav2vec", dim=1280, heads=16, depth=40,
                        head_width=1024, dropout=0.1, attn_dropout=0.1),
}


def preset(name: str, variant: str = "faithful", **overrides) -> TimarConfig:
    """A named configuration of the given variant, with optional field overrides."""
    if name not in PRESETS:
        raise ConfigError(f"unknown TIMAR config {name!r} (known: {', '.join(PRESETS)})")
    return replace(PRESETS[name], variant=variant, **overrides)
