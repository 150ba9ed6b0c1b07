"""SFMS tokenizer: encode/decode contracts, blanked transition frames, dense reconstruction, training."""

import numpy as np
import pytest
import torch

from dyadbench.errors import ConfigError
from models.sfms.config import tokenizer_preset
from models.sfms.data import motion_stats
from models.sfms.tokenizer import SFMSTokenizer
from models.sfms.train_tokenizer import fit_tokenizer, reconstruction_mse

torch.set_num_threads(1)


def micro(**overrides):
    base = dict(width=32, heads=2, ffn=64, pe_dim=8, dropout=0.0)
    return tokenizer_preset("tiny", **{**base, **overrides})


def smooth_windows(n, d=56, seed=0):
    g = np.random.default_rng(seed)
    t = np.arange(48)[None, :, None]
    freq = g.uniform(0.05, 0.3, (n, 1, d))
    phase = g.uniform(0, 6.3, (n, 1, d))
    return np.sin(freq * t + phase).astype(np.float32)


def test_paper_config_has_about_9_6_million_parameters():
    n = sum(p.numel() for p in SFMSTokenizer(tokenizer_preset("paper")).parameters())
    assert 9.4e6 < n < 9.9e6  # paper Table IV: 9.6 M; spec §2.13 hand count 9.69 M
    assert tokenizer_preset("paper").n_classes == 241


def test_encode_gives_exactly_k_keyframes_and_is_deterministic():
    model = SFMSTokenizer(micro(keyframes=7)).eval()
    m = torch.as_tensor(smooth_windows(5))
    classes, mask, codes = model.encode(m)
    assert mask.sum(1).tolist() == [7] * 5
    assert torch.equal(classes > 0, mask)
    assert torch.equal(classes[mask] - 1, codes[mask])
    assert (codes[~mask] == -1).all()
    assert torch.equal(model.encode(m)[0], classes)
    assert model.decode(classes).shape == m.shape


def test_suppression_radius_spaces_the_keyframes_in_encode_and_training():
    model = SFMSTokenizer(micro(keyframes=7, suppression_radius=3)).eval()
    _, mask, _ = model.encode(torch.as_tensor(smooth_windows(5)))
    assert mask.sum(1).tolist() == [7] * 5
    for row in mask.numpy():
        assert np.all(np.diff(np.flatnonzero(row)) > 3)
    losses = model.train()(torch.as_tensor(smooth_windows(4)), generator=torch.Generator().manual_seed(0))
    assert torch.isfinite(losses["loss"]) and losses["mask"] > 0


def test_negative_suppression_radius_is_rejected():
    with pytest.raises(ConfigError, match="suppression_radius"):
        micro(suppression_radius=-1)


@pytest.mark.parametrize("n_kf", [0, 1, 7, 48])
def test_decode_accepts_any_keyframe_count(n_kf):
    model = SFMSTokenizer(micro()).eval()
    classes = torch.zeros(2, 48, dtype=torch.long)
    classes[:, :n_kf] = torch.arange(n_kf) % (model.cfg.n_codes) + 1
    out = model.decode(classes)
    assert out.shape == (2, 48, 56) and torch.isfinite(out).all()


def test_inpainter_never_reads_transition_frames():
    model = SFMSTokenizer(micro()).eval()
    m = torch.as_tensor(smooth_windows(3))
    hard = model.select(m)
    changed = m.clone()
    changed[hard < 0.5] = torch.randn_like(changed[hard < 0.5]) * 10
    outs = []
    for x in (m, changed):
        zq, _, _ = model.quantize(model.encode_keyframes(x, hard), hard)
        outs.append(model.inpaint(zq, hard, hard))
    torch.testing.assert_close(outs[0], outs[1])


@pytest.mark.parametrize("mode, expected", [("static", [0, 8, 16, 24, 32, 40]), ("dense", list(range(48)))])
def test_fixed_arms_use_their_masks(mode, expected):
    model = SFMSTokenizer(micro(keyframe_mode=mode, keyframes=6)).eval()
    _, mask, _ = model.encode(torch.as_tensor(smooth_windows(2)))
    assert np.flatnonzero(mask[1].numpy()).tolist() == expected


def test_with_all_frames_as_keyframes_the_inpainter_reconstructs_its_input():
    """Dense arm, overfitting 4 windows: the decoded keyframes reproduce the input (rel. MSE < 5 %)."""
    windows = smooth_windows(4, d=8)
    cfg = micro(dim=8, keyframe_mode="dense", fsq_levels=(8, 8, 8), steps=150, batch=4, lr_main=3e-3,
                val_every=150, width=48, ffn=96)
    model, _ = fit_tokenizer(cfg, list(windows), windows, motion_mean=np.zeros(8), motion_std=np.ones(8),
                             seed=0, progress=False)
    err = reconstruction_mse(model, windows)["mse_z"]
    assert err < 0.05 * float(windows.var())


def test_training_steps_lower_the_loss_and_step_both_optimisers():
    windows = smooth_windows(64)
    cfg = micro(steps=30, batch=16, warmup_frac=0.2, val_every=30)
    model, history = fit_tokenizer(cfg, list(windows), windows[:8], motion_mean=np.zeros(56),
                                   motion_std=np.ones(56), seed=0, progress=False)
    first = np.mean([s["motion"] for s in history["steps"][:3]])
    last = np.mean([s["motion"] for s in history["steps"][-3:]])
    assert last < 0.8 * first
    steps = history["steps"]
    assert steps[0]["mask"] == 0.0 and steps[-1]["mask"] > 0.0  # scorer frozen in warm-up, trained after
    assert steps[-1]["tau"] < cfg.tau_start
    torch.manual_seed(0)  # fit_tokenizer seeds the same way before building the model
    fresh = SFMSTokenizer(cfg)
    moved = [not torch.equal(a, b) for a, b in zip(fresh.scorer.parameters(), model.scorer.parameters())]
    assert all(moved)


def test_best_sample_target_and_recon_modes_run():
    m = torch.as_tensor(smooth_windows(4))
    for recon_on in ("all", "best"):
        model = SFMSTokenizer(micro(recon_on=recon_on, gumbel_samples=3))
        losses = model(m, generator=torch.Generator().manual_seed(0))
        assert losses["best_err"] <= losses["mean_err"] + 1e-7
        assert torch.isfinite(losses["loss"])


def test_vq_arm_trains_a_step():
    m = torch.as_tensor(smooth_windows(4))
    model = SFMSTokenizer(micro(quantizer="vq", vq_codes=16))
    losses = model(m, generator=torch.Generator().manual_seed(0))
    assert losses["q"] > 0
    losses["loss"].backward()
    assert model.quantizer.codebook.grad.abs().sum() > 0


def test_normalisation_round_trip():
    model = SFMSTokenizer(micro())
    model.motion_mean.fill_(2.0)
    model.motion_std.fill_(3.0)
    x = torch.randn(2, 48, 56)
    torch.testing.assert_close(model.denormalise(model.normalise(x)), x)


def test_ema_weights_are_what_is_kept():
    windows = smooth_windows(16)
    drift = {}
    for decay in (0.0, 0.999):
        cfg = micro(steps=8, batch=8, val_every=8, ema_decay=decay, lr_main=1e-2)
        torch.manual_seed(0)
        init = SFMSTokenizer(cfg).state_dict()
        model, _ = fit_tokenizer(cfg, list(windows), windows[:4], motion_mean=np.zeros(56),
                                 motion_std=np.ones(56), seed=0, progress=False)
        drift[decay] = float((model.out.weight.detach() - init["out.weight"]).abs().max())
    assert drift[0.999] < 0.1 * drift[0.0]  # the slow average barely moves from the initial weights


def test_motion_stats_by_hand_zscore_and_within_sequence():
    """Two 1-d sequences [0, 2] and [10, 12]: mean 6; all-frame std sqrt((36+16+16+36)/4) = sqrt(26);
    pooled within-sequence std sqrt((1+1+1+1)/4) = 1."""
    arrays = [np.array([[0.0], [2.0]]), np.array([[10.0], [12.0]])]
    mean, std = motion_stats(arrays)
    assert mean[0] == pytest.approx(6.0) and std[0] == pytest.approx(np.sqrt(26.0))
    mean_w, std_w = motion_stats(arrays, "within-sequence")
    assert mean_w[0] == pytest.approx(6.0) and std_w[0] == pytest.approx(1.0)
    assert motion_stats([np.ones((5, 2))], "within-sequence")[1].tolist() == pytest.approx([1e-4, 1e-4])
