"""wav2vec 2.0 speech features aligned to motion frames, as TIMAR computes its speech tokens.

Weights are loaded only from disk: a model folder, or a model name already in the local Hugging Face
cache (``local_files_only=True``); nothing is ever downloaded. Without them, :func:`load_wav2vec` raises a
:class:`~dyadbench.errors.ConfigError` saying what is missing; the log-mel frontend
(:mod:`dyadbench.features.logmel`) is the default that needs no weights.

Pipeline (TIMAR's released implementation, ``facebook/wav2vec2-large-960h-lv60-self``):

1. normalise the waveform: (x - mean) / sqrt(var + 1e-7) in float32, as the release's feature extractor
   does, with the mean and variance of the whole waveform given, or with ``stats`` passed in (the
   protocol's ``--speech-norm clip``: the whole clip's, as the released evaluation normalises each clip);
2. cut it into 1-s chunks of 16,000 samples (the last one zero-padded);
3. per chunk, the convolutional feature extractor: 49 frames of 512-d at ~50 Hz;
4. linear interpolation to 25 frames (``align_corners=True``);
5. the model's feature projection and transformer encoder, per chunk;
6. the frames of all chunks concatenated and cut to floor(len(audio) / 640) motion frames.

Output: (T, hidden_size) float32 (1024 for large models, 768 for base). Each chunk is encoded on its
own, so a turn's features depend only on that turn's samples once the waveform is normalised (step 1
uses the statistics of the whole waveform passed in unless ``stats`` are given).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from dyadbench.errors import ConfigError, InputError

DEFAULT_MODEL = "facebook/wav2vec2-large-960h-lv60-self"
CHUNK_SECONDS = 1.0
NORM_EPS = 1e-7


def _missing(source: str, reason: str) -> ConfigError:
    cache = os.environ.get("HF_HUB_CACHE") or os.environ.get("HF_HOME") or "~/.cache/huggingface"
    return ConfigError(
        f"wav2vec 2.0 weights {source!r} are not available locally ({reason}). dyadbench never downloads "
        f"weights: pass the path of a downloaded model folder (config.json + weights), or place the model in "
        f"the Hugging Face cache ({cache}). Without them, use the default log-mel speech features "
        f"(dyadbench.features.logmel).")


def load_wav2vec(source: str | Path = DEFAULT_MODEL, device: str = "cpu"):
    """A frozen ``transformers`` Wav2Vec2Model from a local folder or the local cache (never the network)."""
    try:
        from transformers import Wav2Vec2Model
    except ImportError:
        raise ConfigError("wav2vec 2.0 features need the `transformers` package: pip install 'dyadbench[wav2vec]' "
                          "(or use the default log-mel speech features, dyadbench.features.logmel)") from None
    path = Path(source).expanduser()
    if not path.is_dir() and (path.is_absolute() or str(source).startswith((".", "~"))):
        raise _missing(str(source), "no such folder")
    try:
        model = Wav2Vec2Model.from_pretrained(str(path) if path.is_dir() else str(source), local_files_only=True)
    except (OSError, ValueError) as exc:
        raise _missing(str(source), f"{type(exc).__name__}: {str(exc).splitlines()[0]}") from None
    model.eval().requires_grad_(False)
    return model.to(device)


def waveform_stats(audio: np.ndarray) -> tuple[float, float]:
    """(mean, variance) of a waveform, computed in float32 as the release's feature extractor does."""
    x = np.asarray(audio, dtype=np.float32)
    return float(x.mean()), float(x.var())


def normalise(audio: np.ndarray, stats: tuple[float, float] | None = None) -> np.ndarray:
    """(x - mean) / sqrt(var + 1e-7) in float32, with ``stats`` = (mean, var) or the waveform's own."""
    x = np.asarray(audio, dtype=np.float32)
    mean, var = stats if stats is not None else waveform_stats(x)
    return (x - np.float32(mean)) / np.sqrt(np.float32(var) + np.float32(NORM_EPS))


def chunk_features(model, chunks, frames_per_chunk: int = 25):
    """(B, samples) normalised chunks -> (B, frames_per_chunk, hidden) torch tensor (steps 3-5)."""
    import torch
    import torch.nn.functional as F

    with torch.no_grad():
        extracted = model.feature_extractor(chunks)  # (B, 512, 49)
        resampled = F.interpolate(extracted, size=frames_per_chunk, mode="linear", align_corners=True)
        hidden, _ = model.feature_projection(resampled.transpose(1, 2))
        return model.encoder(hidden).last_hidden_state


def wav2vec_frames(model, audio: np.ndarray, sample_rate: int = 16_000, fps: float = 25.0,
                   batch_size: int = 16, stats: tuple[float, float] | None = None) -> np.ndarray:
    """(floor(len(audio) * fps / sample_rate), hidden_size) float32 features (see the module docstring);
    ``stats``: (mean, var) to normalise with instead of the waveform's own."""
    import torch

    audio = np.asarray(audio)
    if audio.ndim != 1:
        raise InputError(None, f"wav2vec features need mono audio (S,), got shape {audio.shape}")
    if sample_rate != 16_000:
        raise InputError(None, f"wav2vec 2.0 expects 16 kHz audio, got {sample_rate} Hz")
    chunk = int(round(CHUNK_SECONDS * sample_rate))
    per_chunk = int(round(CHUNK_SECONDS * fps))
    n_frames = int(len(audio) * fps // sample_rate)
    hidden = model.config.hidden_size
    if n_frames == 0:
        return np.zeros((0, hidden), dtype=np.float32)
    x = normalise(audio, stats)
    n_chunks = -(-len(x) // chunk)
    x = np.pad(x, (0, n_chunks * chunk - len(x))).reshape(n_chunks, chunk)
    device = next(model.parameters()).device
    out = [chunk_features(model, torch.from_numpy(x[i:i + batch_size]).to(device), per_chunk)
           for i in range(0, n_chunks, batch_size)]
    return torch.cat(out).reshape(-1, hidden)[:n_frames].cpu().numpy().astype(np.float32)
