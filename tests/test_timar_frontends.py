"""TIMAR speech frontends: per-turn log-mel chunks, the wav2vec 2.0 frontend on a tiny local model."""

from __future__ import annotations

import numpy as np
import pytest

from dyadbench.errors import ConfigError
from dyadbench.features.logmel import logmel_frames
from models.timar.config import preset
from models.timar.frontends import LogMelFrontend, Wav2VecFrontend, make_frontend


def test_logmel_features_are_computed_turn_by_turn():
    audio = np.random.default_rng(0).normal(0, 0.1, 3 * 16_000).astype(np.float32)
    feats = LogMelFrontend(preset("tiny")).features(audio, 3)
    assert feats.shape == (75, 40)
    np.testing.assert_array_equal(feats[25:50], logmel_frames(audio[16_000:32_000]))
    later = audio.copy()
    later[32_000:] = 1.0  # a later turn never changes an earlier turn's features
    np.testing.assert_array_equal(LogMelFrontend(preset("tiny")).features(later, 3)[:50], feats[:50])


def test_paper_sizes_need_local_wav2vec_weights(tmp_path):
    pytest.importorskip("transformers")
    with pytest.raises(ConfigError, match="never downloads"):
        make_frontend(preset("large"), wav2vec_weights=str(tmp_path / "absent"))


def test_wav2vec_frontend_runs_the_shared_pipeline(tmp_path):
    transformers = pytest.importorskip("transformers")
    import torch

    from dyadbench.features.wav2vec import load_wav2vec, wav2vec_frames

    torch.manual_seed(0)
    config = transformers.Wav2Vec2Config(
        hidden_size=32, num_hidden_layers=1, num_attention_heads=2, intermediate_size=48, conv_dim=(16,) * 7,
        num_conv_pos_embeddings=16, num_conv_pos_embedding_groups=2, feat_extract_norm="layer",
        do_stable_layer_norm=True)
    transformers.Wav2Vec2Model(config).save_pretrained(tmp_path)
    audio = np.random.default_rng(1).normal(0, 0.1, 2 * 16_000 + 700).astype(np.float32)
    frontend = Wav2VecFrontend(preset("base"), weights=str(tmp_path))
    model = load_wav2vec(tmp_path)
    feats = frontend.features(audio, 2)  # --speech-norm window: each 1-s turn normalised on its own
    assert feats.shape == (50, 32) and frontend.dim == 32
    per_turn = np.concatenate([wav2vec_frames(model, audio[i * 16_000:(i + 1) * 16_000]) for i in range(2)])
    np.testing.assert_allclose(feats, per_turn, atol=1e-6)
    clip = frontend.features(audio, 2, stats=(float(audio.mean()), float(audio.var())))  # the release's
    np.testing.assert_allclose(clip, wav2vec_frames(model, audio[:32_000], stats=(audio.mean(), audio.var())),
                               atol=1e-6)
    assert np.abs(clip - feats).max() > 1e-3  # the two normalisations differ
