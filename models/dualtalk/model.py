"""The DualTalk network, as released (all modules batch-first; module names are the checkpoint's).

Causal graph (B = batch, T' = frames of the agent's audio, Tm = partner-motion frames; nothing is causal,
the BiLSTM and every attention read the whole sequence)::

    a1 = P(S1(audio1, T'))      a2 = P(S2(audio2, T'))         (B, T', F)   P = shared audio_projection
    m  = ReLU(L2(ReLU(L1(blendshape2))))                       (B, Tm, F)   blendshape_encoder
    e  = BiLSTM(MHA(q = a2, k = v = m))                        (B, T', F)   temporal_enhancer
    i  = Dropout0.5(MHA(x, x, x)),  x = TransformerEncoder([a1 | e])   (B, T', 2F)  interaction_module
    y  = TransformerDecoder(tgt = i, memory = i);  y = y + 0.1 Linear(y);  out = Linear(y)  (B, T', 56)

``S_k`` is wav2vec 2.0 encoder k (``released``: its CNN features interpolated to T' frames before the
feature projection, :func:`wav2vec_states`) or, for ``logmel``, the standardisation of log-mel frames
with training statistics (buffers ``joint_encoder.speech_mean`` / ``speech_std``).
"""

from __future__ import annotations

import torch
import torch.nn.functional as F
from torch import nn

from models.dualtalk.config import DualTalkConfig


def wav2vec_states(model: nn.Module, audio: torch.Tensor, frames: int) -> torch.Tensor:
    """A transformers ``Wav2Vec2Model`` on a (B, N) normalised waveform, its CNN features (~50 Hz) linearly
    interpolated to ``frames`` (``align_corners=True``) before the feature projection -> (B, frames, hidden)."""
    extracted = F.interpolate(model.feature_extractor(audio), size=frames, mode="linear", align_corners=True)
    hidden, _ = model.feature_projection(extracted.transpose(1, 2))
    return model.encoder(hidden).last_hidden_state


class JointEncoder(nn.Module):
    def __init__(self, cfg: DualTalkConfig, wav2vec_config=None):
        super().__init__()
        self.cfg = cfg
        if cfg.speech_frontend == "wav2vec":
            from transformers import Wav2Vec2Model  # noqa: PLC0415  (only the released size needs it)

            if wav2vec_config is None:
                raise ValueError("the wav2vec front end needs a wav2vec 2.0 config")
            self.audio_encoder1 = Wav2Vec2Model(wav2vec_config)
            self.audio_encoder2 = Wav2Vec2Model(wav2vec_config)
        else:
            self.register_buffer("speech_mean", torch.zeros(cfg.speech_dim))
            self.register_buffer("speech_std", torch.ones(cfg.speech_dim))
        self.audio_projection = nn.Linear(cfg.speech_dim, cfg.feature_dim)
        half = cfg.feature_dim // 2
        self.blendshape_encoder = nn.Sequential(nn.Linear(cfg.motion_dim, half), nn.ReLU(),
                                                nn.Linear(half, cfg.feature_dim), nn.ReLU())

    def speech_states(self, speech: torch.Tensor, which: int, frames: int) -> torch.Tensor:
        """wav2vec: (B, N) waveform -> (B, frames, hidden); logmel: (B, frames, bands) -> standardised."""
        if self.cfg.speech_frontend == "wav2vec":
            encoder = self.audio_encoder1 if which == 1 else self.audio_encoder2
            return wav2vec_states(encoder, speech, frames)
        return (speech[:, :frames] - self.speech_mean) / self.speech_std

    def forward(self, speech1: torch.Tensor, speech2: torch.Tensor, blendshape2: torch.Tensor, frames: int):
        audio_feat1 = self.audio_projection(self.speech_states(speech1, 1, frames))
        audio_feat2 = self.audio_projection(self.speech_states(speech2, 2, frames))
        return audio_feat1, audio_feat2, self.blendshape_encoder(blendshape2)


class CrossModalTemporalEnhancer(nn.Module):
    def __init__(self, cfg: DualTalkConfig):
        super().__init__()
        self.cross_attention = nn.MultiheadAttention(cfg.feature_dim, cfg.heads, batch_first=True)
        self.temporal_lstm = nn.LSTM(cfg.feature_dim, cfg.feature_dim // 2, num_layers=2, batch_first=True,
                                     bidirectional=True)

    def forward(self, partner_audio: torch.Tensor, partner_motion: torch.Tensor) -> torch.Tensor:
        attended, _ = self.cross_attention(partner_audio, partner_motion, partner_motion, need_weights=False)
        return self.temporal_lstm(attended)[0]


def _layer_kwargs(cfg: DualTalkConfig) -> dict:
    return {"d_model": 2 * cfg.feature_dim, "nhead": cfg.heads, "dim_feedforward": cfg.ff_dim,
            "dropout": cfg.dropout, "batch_first": True}


class DualSpeakerInteractionModule(nn.Module):
    def __init__(self, cfg: DualTalkConfig):
        super().__init__()
        self.interaction_encoder = nn.TransformerEncoder(nn.TransformerEncoderLayer(**_layer_kwargs(cfg)),
                                                         num_layers=3, enable_nested_tensor=False)
        self.self_attention = nn.MultiheadAttention(2 * cfg.feature_dim, cfg.heads, batch_first=True)
        self.dropout = nn.Dropout(cfg.interaction_dropout)

    def forward(self, agent_audio: torch.Tensor, enhanced: torch.Tensor) -> torch.Tensor:
        x = self.interaction_encoder(torch.cat([agent_audio, enhanced], dim=-1))
        return self.dropout(self.self_attention(x, x, x, need_weights=False)[0])


class SynthesisModule(nn.Module):
    def __init__(self, cfg: DualTalkConfig):
        super().__init__()
        self.synthesis_decoder = nn.TransformerDecoder(nn.TransformerDecoderLayer(**_layer_kwargs(cfg)), num_layers=1)
        self.modulation_layer = nn.Linear(2 * cfg.feature_dim, 2 * cfg.feature_dim)
        self.blendshape_predictor = nn.Linear(2 * cfg.feature_dim, cfg.motion_dim)
        self.modulation = cfg.modulation

    def forward(self, interaction: torch.Tensor) -> torch.Tensor:
        y = self.synthesis_decoder(interaction, interaction)
        return self.blendshape_predictor(y + self.modulation * self.modulation_layer(y))


class DualTalkModel(nn.Module):
    """``forward(speech1, speech2, blendshape2, frames)`` -> the agent's motion (B, frames, 56).

    ``speech1`` is the agent's own speech, ``speech2`` the partner's (waveforms for ``wav2vec``, log-mel
    frames for ``logmel``), ``blendshape2`` the partner's motion. :meth:`stages` returns every intermediate.
    """

    def __init__(self, cfg: DualTalkConfig, wav2vec_config=None):
        super().__init__()
        self.cfg = cfg
        self.joint_encoder = JointEncoder(cfg, wav2vec_config)
        self.temporal_enhancer = CrossModalTemporalEnhancer(cfg)
        self.interaction_module = DualSpeakerInteractionModule(cfg)
        self.synthesis_module = SynthesisModule(cfg)

    def stages(self, speech1, speech2, blendshape2, frames: int) -> dict[str, torch.Tensor]:
        audio_feat1, audio_feat2, blendshape_feat = self.joint_encoder(speech1, speech2, blendshape2, frames)
        temporal_feat = self.temporal_enhancer(audio_feat2, blendshape_feat)
        interaction_feat = self.interaction_module(audio_feat1, temporal_feat)
        return {"audio_feat1": audio_feat1, "audio_feat2": audio_feat2, "blendshape_feat": blendshape_feat,
                "temporal_feat": temporal_feat, "interaction_feat": interaction_feat,
                "output": self.synthesis_module(interaction_feat)}

    def forward(self, speech1, speech2, blendshape2, frames: int) -> torch.Tensor:
        return self.stages(speech1, speech2, blendshape2, frames)["output"]
