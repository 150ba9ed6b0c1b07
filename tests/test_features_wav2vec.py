"""wav2vec 2.0 features: the TIMAR pipeline on a tiny random model saved to disk; absent weights."""

import numpy as np
import pytest

from dyadbench.errors import ConfigError

transformers = pytest.importorskip("transformers")
torch = pytest.importorskip("torch")

from dyadbench.features.wav2vec import chunk_features, load_wav2vec, normalise, wav2vec_frames  # noqa: E402


@pytest.fixture(scope="module")
def tiny_model_dir(tmp_path_factory):
    torch.manual_seed(0)
    config = transformers.Wav2Vec2Config(
        hidden_size=32, num_hidden_layers=2, num_attention_heads=2, intermediate_size=48,
        conv_dim=(16,) * 7, num_conv_pos_embeddings=16, num_conv_pos_embedding_groups=2,
        feat_extract_norm="layer", do_stable_layer_norm=True)  # the large-lv60 architecture, tiny
    folder = tmp_path_factory.mktemp("w2v")
    transformers.Wav2Vec2Model(config).save_pretrained(folder)
    return folder


def test_frames_shape_and_chunk_pipeline(tiny_model_dir):
    model = load_wav2vec(tiny_model_dir)
    audio = np.random.default_rng(0).normal(0, 0.1, 16_000 * 2 + 5_000).astype(np.float32)
    feats = wav2vec_frames(model, audio)
    assert feats.shape == (int((16_000 * 2 + 5_000) // 640), 32) and feats.dtype == np.float32
    assert np.all(np.isfinite(feats))
    # chunk 1 computed by hand: conv features (49 frames) -> linear interp to 25 -> projection -> encoder
    x = torch.from_numpy(normalise(audio)[16_000:32_000])[None]
    with torch.no_grad():
        conv = model.feature_extractor(x)
        assert conv.shape[-1] == 49
        interp = torch.nn.functional.interpolate(conv, size=25, mode="linear", align_corners=True)
        assert torch.allclose(interp[..., 0], conv[..., 0]) and torch.allclose(interp[..., -1], conv[..., -1])
        hidden, _ = model.feature_projection(interp.transpose(1, 2))
        expected = model.encoder(hidden).last_hidden_state[0].numpy()
    np.testing.assert_allclose(feats[25:50], expected, rtol=1e-5, atol=1e-5)


def test_chunks_are_encoded_independently(tiny_model_dir):
    model = load_wav2vec(tiny_model_dir)
    rng = np.random.default_rng(1)
    chunks = torch.from_numpy(rng.normal(size=(2, 16_000)).astype(np.float32))
    changed = chunks.clone()
    changed[1] = torch.from_numpy(rng.normal(size=16_000).astype(np.float32))
    a, b = chunk_features(model, chunks), chunk_features(model, changed)
    assert torch.allclose(a[0], b[0]) and not torch.allclose(a[1], b[1])


def test_normalise_whole_waveform():
    x = normalise(np.arange(10, dtype=np.float32))
    assert abs(x.mean()) < 1e-6 and abs(x.std() - 1) < 1e-5


def test_absent_weights_say_what_is_missing(tmp_path):
    with pytest.raises(ConfigError, match="not-there.*no such folder.*log-mel"):
        load_wav2vec(tmp_path / "not-there")
    # a model name that is in no local cache: refused without any network access
    with pytest.raises(ConfigError, match="dyadbench-tests/absent-wav2vec.*never downloads.*log-mel"):
        load_wav2vec("dyadbench-tests/absent-wav2vec")
