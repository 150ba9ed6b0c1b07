"""DualTalk configurations: ``released`` (the published sizes, two wav2vec 2.0 encoders) and ``tiny``
(log-mel speech, CPU-trainable; the shipped checkpoint).

The released network fixes 4 attention heads, a 2-layer BiLSTM of hidden F/2 per direction, a 3-layer
post-norm ReLU TransformerEncoder and a 1-layer TransformerDecoder of width 2F with PyTorch's default
feed-forward width 2048, dropout 0.1 inside the Transformer layers, dropout 0.5 after the interaction
self-attention and a modulation factor 0.1. ``tiny`` keeps all of that except F = 64 and a feed-forward
width of 256, and replaces the two wav2vec 2.0 encoders by 40-band log-mel frames
(:func:`dyadbench.features.logmel.logmel_frames`) standardised with training statistics.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

from dyadbench.errors import ConfigError
from dyadbench.training.config import config_from_dict, config_to_dict

MOTION_DIM = 56
FRONTENDS = ("wav2vec", "logmel")
LOGMEL_BANDS = 40


@dataclass(frozen=True)
class DualTalkConfig:
    name: str = "tiny"
    feature_dim: int = 64  # F (256 released)
    ff_dim: int = 256  # feed-forward width of the Transformer layers (2048 released)
    heads: int = 4
    speech_frontend: str = "logmel"  # "wav2vec" (released: two encoders) or "logmel"
    speech_dim: int = LOGMEL_BANDS  # input width of audio_projection (wav2vec hidden size, or mel bands)
    motion_dim: int = MOTION_DIM
    dropout: float = 0.1  # inside the Transformer layers
    interaction_dropout: float = 0.5  # after the interaction self-attention
    modulation: float = 0.1  # x + modulation * Linear(x) in the synthesis module

    def __post_init__(self) -> None:
        if self.speech_frontend not in FRONTENDS:
            raise ConfigError(f"speech_frontend must be one of {FRONTENDS}, got {self.speech_frontend!r}")
        if self.feature_dim < 2 or self.feature_dim % 2 or self.feature_dim % self.heads:
            raise ConfigError(f"feature_dim must be even (F/2 LSTM units) and a multiple of heads={self.heads}, "
                              f"got {self.feature_dim}")

    def to_dict(self) -> dict:
        return config_to_dict(self)

    @classmethod
    def from_dict(cls, data: dict) -> "DualTalkConfig":
        return config_from_dict(cls, data)


PRESETS = {
    "tiny": DualTalkConfig(),
    "released": DualTalkConfig(name="released", feature_dim=256, ff_dim=2048, speech_frontend="wav2vec",
                               speech_dim=1024),
}


def preset(name: str, **overrides) -> DualTalkConfig:
    if name not in PRESETS:
        raise ConfigError(f"unknown DualTalk config {name!r} (known: {', '.join(PRESETS)})")
    return replace(PRESETS[name], **overrides)
