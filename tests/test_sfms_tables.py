"""SFMS Table III/IV pieces: the dense VQ-VAE arm, listening-frame windows and masked MSE, bits per window."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from dyadbench.datasets.base import DyadicClip, Participant
from models.sfms.ablation import (agent_motions_and_masks, code_usage, frame_errors, masked_windows, mse_by_cut,
                                  window_bits)
from models.sfms.config import tokenizer_preset
from models.sfms.dense_vq import DenseVQVAE
from models.sfms.train_tokenizer import fit_tokenizer


def _cfg(**over):
    base = dict(keyframe_mode="dense", quantizer="vq", vq_codes=16, normalisation="zscore")
    return tokenizer_preset("tiny", **{**base, **over})


def test_dense_vqvae_shapes_losses_and_gradients():
    torch.manual_seed(0)
    model = DenseVQVAE(_cfg(), downsample=8).eval()  # eval: no dropout, reconstruct = decode ∘ encode
    m = torch.randn(3, 48, 56)
    codes = model.encode(m)
    assert codes.shape == (3, 6) and codes.dtype == torch.long
    assert int(codes.min()) >= 0 and int(codes.max()) < 16
    assert model.decode(codes).shape == (3, 48, 56)
    assert torch.equal(model.reconstruct(m), model.decode(codes))
    losses = model.train()(m)
    assert losses["codes"].shape == (3, 6)
    assert torch.isclose(losses["loss"], losses["motion"] + losses["q"])
    losses["loss"].backward()
    assert model.patch.weight.grad is not None and model.quantizer.codebook.grad is not None
    assert model.scorer_parameters() == [] and len(model.main_parameters()) == len(list(model.parameters()))


@pytest.mark.parametrize("bad", [dict(downsample=5), dict(downsample=0)])
def test_dense_vqvae_refuses_a_downsample_that_does_not_divide_the_window(bad):
    with pytest.raises(ValueError, match="downsample"):
        DenseVQVAE(_cfg(), **bad)


def test_dense_vqvae_refuses_fsq():
    with pytest.raises(ValueError, match="VQ codebook"):
        DenseVQVAE(_cfg(quantizer="fsq"))


def _linear_model(downsample: int, codebook: torch.Tensor) -> DenseVQVAE:
    """d = 2, zero transformer layers, identity patch maps, zero positions: frames → VQ → frames."""
    d, w = 2, 2 * downsample
    cfg = _cfg(dim=d, width=w, heads=1, ffn=4, window=8, keyframe_layers=0, decoder_layers=0,
               vq_codes=len(codebook))
    model = DenseVQVAE(cfg, downsample=downsample)
    eye = torch.zeros(w, d, downsample)
    for j in range(downsample):  # latent channel c + d·j = input channel c at frame j of the group
        for c in range(d):
            eye[c + d * j, c, j] = 1.0
    with torch.no_grad():
        model.patch.weight.copy_(eye)
        model.patch.bias.zero_()
        model.unpatch.weight.copy_(eye)  # ConvTranspose1d weight (in = w, out = d, kernel)
        model.unpatch.bias.zero_()
        model.encoder_pe.zero_()
        model.decoder_pe.zero_()
        model.quantizer.codebook.copy_(codebook)
    return model.eval()


@pytest.mark.parametrize("downsample", [1, 2])
def test_a_signal_made_of_codebook_entries_is_reconstructed_exactly(downsample):
    # codebook entries are groups of `downsample` frames of 2 dims, flattened channel-fastest
    rng = np.random.default_rng(0)
    codebook = torch.as_tensor(rng.normal(size=(5, 2 * downsample)), dtype=torch.float32)
    want = torch.tensor([[3, 0, 3, 1, 0, 3, 1, 3][: 8 // downsample]])
    model = _linear_model(downsample, codebook)
    groups = codebook[want]  # (1, tokens, 2·downsample)
    m = groups.reshape(1, 8 // downsample, downsample, 2).reshape(1, 8, 2)
    assert torch.equal(model.encode(m), want)
    assert torch.allclose(model.reconstruct(m), m, atol=1e-6)
    losses = model(m)
    assert float(losses["q"].detach()) < 1e-10 and float(losses["motion"].detach()) < 1e-10
    # codebook usage: the signal uses 3 of the 5 codes ({0, 1, 3}) with either grouping
    assert code_usage(model.encode(m), 5) == len(set(want.flatten().tolist())) / 5


def test_a_signal_off_the_codebook_snaps_to_the_nearest_entry():
    codebook = torch.tensor([[0.0, 0.0], [1.0, 1.0], [-1.0, 2.0]])
    model = _linear_model(1, codebook)
    m = torch.tensor([[[0.1, -0.1], [0.9, 1.2], [-0.8, 1.7], [0.0, 0.4]] * 2])
    rec = model.reconstruct(m)
    assert torch.equal(rec, codebook[torch.tensor([0, 1, 2, 0] * 2)][None])


def test_fit_tokenizer_trains_the_dense_vqvae_with_validation_selection():
    rng = np.random.default_rng(1)
    train = [rng.normal(size=(120, 56)).astype(np.float32) for _ in range(3)]
    val = rng.normal(size=(4, 48, 56)).astype(np.float32)
    cfg = _cfg(steps=4, batch=2, val_every=2)
    model, history = fit_tokenizer(cfg, train, val, motion_mean=np.zeros(56, np.float32),
                                   motion_std=np.ones(56, np.float32), seed=0, progress=False,
                                   model_factory=lambda c: DenseVQVAE(c, downsample=4))
    assert isinstance(model, DenseVQVAE) and not model.training
    assert [v["step"] for v in history["val"]] == [2, 4] and history["best_step"] in (2, 4)


def _clip(t: int, own: list[int], other: list[int]) -> DyadicClip:
    people = tuple(Participant(name, np.arange(t * 56, dtype=np.float32).reshape(t, 56) + 1000 * i,
                               np.zeros(640 * t)) for i, name in enumerate(("speaker1", "speaker2")))
    return DyadicClip("c0", people, meta={"speaking": {"speaker1": np.array(own, bool),
                                                       "speaker2": np.array(other, bool)}})


def test_listening_windows_carry_each_agents_mask():
    own = [1, 1, 0, 0, 0, 1, 0, 0, 1, 1]
    other = [0, 1, 1, 0, 1, 1, 1, 1, 0, 0]
    clip = _clip(10, own, other)
    motions, masks = agent_motions_and_masks([clip], np.zeros(56, np.float32), np.full(56, 2.0, np.float32))
    assert masks[0].tolist() == [0, 0, 1, 0, 1, 0, 1, 1, 0, 0]  # speaker1 silent and speaker2 speaking
    assert masks[1].tolist() == [1, 0, 0, 0, 0, 0, 0, 0, 1, 1]
    windows, frames = masked_windows(motions, masks, window=4, limit=10)
    assert windows.shape == (4, 4, 56) and frames.shape == (4, 4)  # 2 windows per agent, frames 8–9 dropped
    assert frames.tolist() == [[0, 0, 1, 0], [1, 0, 1, 1], [1, 0, 0, 0], [0, 0, 0, 0]]
    np.testing.assert_array_equal(windows[1], clip.participants[0].motion[4:8] / 2.0)
    np.testing.assert_array_equal(windows[2], clip.participants[1].motion[0:4] / 2.0)


def test_masked_windows_refuses_masks_of_another_length():
    with pytest.raises(ValueError, match="frame mask"):
        masked_windows([np.zeros((8, 2), np.float32)], [np.zeros(7, bool)], window=4, limit=4)


def test_mse_by_cut_averages_the_listening_frames_by_hand():
    errors = np.array([[1.0, 2.0, 3.0, 4.0], [5.0, 6.0, 7.0, 8.0]])
    masks = np.array([[0, 1, 0, 1], [1, 0, 0, 0]], bool)
    got = mse_by_cut(errors, 10 * errors, masks)
    assert got["mse_z"] == pytest.approx(4.5) and got["mse_raw"] == pytest.approx(45.0)
    assert got["listen_mse_z"] == pytest.approx((2 + 4 + 5) / 3)
    assert got["listen_mse_raw"] == pytest.approx(10 * (2 + 4 + 5) / 3)
    assert got["listen_frames"] == 3 and got["frames"] == 8
    assert math.isnan(mse_by_cut(errors, errors, np.zeros_like(masks))["listen_mse_z"])


def test_frame_errors_are_per_frame_means_over_dims_in_both_units():
    class Shift(torch.nn.Module):  # reconstructs every value + 1 (z), raw = z · 3
        def reconstruct(self, m):
            return m + 1.0

        def denormalise(self, m):
            return 3.0 * m

    z, raw = frame_errors(Shift(), np.zeros((2, 5, 4), np.float32), batch=1)
    np.testing.assert_allclose(z, np.ones((2, 5)))
    np.testing.assert_allclose(raw, np.full((2, 5), 9.0))


def test_window_bits_by_hand():
    # log2 240 = 7.9068906, C(48, 3) = 17296 (log2 14.0781508), C(48, 7) = 73629072 (log2 26.1337722)
    assert window_bits(3, 240) == pytest.approx(23.720672, abs=1e-5)  # static k = 3
    assert window_bits(3, 240, 1, 48, 3) == pytest.approx(37.798823, abs=1e-5)  # dynamic k = 3
    assert window_bits(7, 240, 1, 48, 7) == pytest.approx(81.482006, abs=1e-5)  # dynamic k = 7
    assert window_bits(3 * 56, 240, 56, 48, 3) == pytest.approx(168 * 7.9068906 + 56 * 14.0781508, abs=1e-4)
    assert window_bits(6, 240) == pytest.approx(47.441344, abs=1e-5)  # dense VQ-VAE, 8 frames per token
    assert window_bits(48, 2) == 48.0  # dense, one bit per frame
    with pytest.raises(ValueError, match="window_bits"):
        window_bits(3, 0)
