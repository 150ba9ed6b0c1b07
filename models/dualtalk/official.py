"""Loading the released DualTalk checkpoint (``DualTalk.pth``): a bare state dict with both wav2vec models.

Read with :func:`dyadbench.torch_files.load_tensors_only` and no extra globals (the file holds only
tensors). The configuration comes from the tensors' shapes (F from ``joint_encoder.audio_projection``,
the wav2vec width from its in_features, the feed-forward width from the first encoder layer); the wav2vec
2.0 architecture comes from a local model folder (``config.json``; only the config is read: both encoders'
weights are the checkpoint's, and differ from each other and from the pretrained model). The positional
convolution's old ``weight_g`` / ``weight_v`` names load as they are (torch maps them). A key the network
lacks, or a tensor the file lacks, is an error that lists them.
"""

from __future__ import annotations

from pathlib import Path

import torch

from dyadbench.errors import ConfigError, InputError
from dyadbench.torch_files import load_tensors_only
from models.dualtalk.config import preset
from models.dualtalk.model import DualTalkModel

MODULES = ("joint_encoder.", "temporal_enhancer.", "interaction_module.", "synthesis_module.")
PROJECTION = "joint_encoder.audio_projection.weight"
FEED_FORWARD = "interaction_module.interaction_encoder.layers.0.linear1.weight"


def is_official(payload: object) -> bool:
    """A bare state dict (names to tensors) with DualTalk's top-level modules."""
    return (isinstance(payload, dict) and bool(payload)
            and all(isinstance(k, str) and isinstance(v, torch.Tensor) for k, v in payload.items())
            and any(k.startswith(MODULES) for k in payload))


def wav2vec_config(folder: str | Path | None):
    """The ``Wav2Vec2Config`` of a local wav2vec 2.0 model folder (eager attention; nothing downloaded)."""
    if folder is None:
        raise ConfigError("the official DualTalk checkpoint needs the wav2vec 2.0 config: pass the local folder "
                          "of facebook/wav2vec2-large-960h-lv60-self (--wav2vec PATH; only its config.json is read)")
    path = Path(folder).expanduser()
    if not (path / "config.json").is_file():
        raise InputError(path, "not a wav2vec 2.0 model folder (no config.json)")
    from transformers import Wav2Vec2Config  # noqa: PLC0415

    config = Wav2Vec2Config.from_pretrained(str(path), local_files_only=True)
    config._attn_implementation = "eager"
    return config


def load_official(path: str | Path, wav2vec_folder: str | Path | None) -> DualTalkModel:
    """The released network with every tensor of the file (eval mode)."""
    path = Path(path)
    state = load_tensors_only(path, what="DualTalk checkpoint")
    if not is_official(state) or PROJECTION not in state:
        raise InputError(path, "not a DualTalk checkpoint (expected a bare state dict with joint_encoder, "
                               "temporal_enhancer, interaction_module and synthesis_module tensors)")
    return model_from_state(path, state, wav2vec_config(wav2vec_folder))


def model_from_state(path: Path, state: dict, w2v_config) -> DualTalkModel:
    """Build the network the tensors' shapes describe and load them all (strict, errors list the keys)."""
    feature_dim, speech_dim = state[PROJECTION].shape
    if speech_dim != w2v_config.hidden_size:
        raise InputError(path, f"audio_projection expects {speech_dim}-d wav2vec states but the wav2vec config "
                               f"has hidden_size {w2v_config.hidden_size}")
    ff = state[FEED_FORWARD].shape[0] if FEED_FORWARD in state else preset("released").ff_dim
    cfg = preset("released", feature_dim=int(feature_dim), speech_dim=int(speech_dim), ff_dim=int(ff))
    model = DualTalkModel(cfg, w2v_config)
    try:
        result = model.load_state_dict(state, strict=False)
    except RuntimeError as exc:
        raise InputError(path, f"tensor shapes do not fit the DualTalk network: {exc}") from None
    problems = [f"{label}: {', '.join(sorted(keys))}" for label, keys in
                (("missing", result.missing_keys), ("unexpected", result.unexpected_keys)) if keys]
    if problems:
        raise InputError(path, "checkpoint does not match the DualTalk network; " + "; ".join(problems))
    return model.eval()

