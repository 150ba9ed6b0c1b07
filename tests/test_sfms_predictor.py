"""SFMS predictor: loss arithmetic (eq. 14, group weights, soft-DTW), speaker span, training."""

import numpy as np
import pytest
import torch
from hypothesis import given, settings, strategies as st

from dyadbench.synth.corpus import make_clips
from models.sfms.config import predictor_preset, tokenizer_preset
from models.sfms.data import directed_clips, normalise_directed, sample_predictor_batch
from models.sfms.predictor import SFMSPredictor, class_weights, predictor_losses
from models.sfms.soft_dtw import soft_dtw, soft_dtw_divergence
from models.sfms.tokenizer import SFMSTokenizer
from models.sfms.train_predictor import fit_predictor

torch.set_num_threads(1)
MICRO = dict(width=32, heads=2, ffn=64, audio_bins=8, dropout=0.0)


def test_group_class_weights_for_k7_t48():
    w = class_weights(241, 7, 48)
    assert float(w[0]) == pytest.approx(0.5 / (1 - 7 / 48))  # 0.585
    assert float(w[1]) == pytest.approx(0.5 / (7 / 48)) == float(w[240])  # 3.43
    assert float(w[0]) == pytest.approx(0.585, abs=1e-3) and float(w[5]) == pytest.approx(3.429, abs=1e-3)


def test_weighted_ce_is_normalised_by_token_count_not_weight_sum():
    cfg = predictor_preset("tiny", sdtw_weight=0.0)
    logits = torch.zeros(1, 2, 3)  # uniform: NLL = log 3 per token
    targets = torch.tensor([[0, 2]])
    weights = torch.tensor([0.5, 2.0, 2.0])
    ce = predictor_losses(logits, targets, weights, cfg)["ce"]
    assert float(ce) == pytest.approx((0.5 + 2.0) * np.log(3) / 2)


def naive_dtw(x, y):
    n, m = len(x), len(y)
    r = np.full((n + 1, m + 1), np.inf)
    r[0, 0] = 0
    for i in range(1, n + 1):
        for j in range(1, m + 1):
            r[i, j] = (x[i - 1] - y[j - 1]) ** 2 + min(r[i - 1, j - 1], r[i - 1, j], r[i, j - 1])
    return r[n, m]


@settings(max_examples=20, deadline=None)
@given(st.lists(st.floats(0, 1), min_size=1, max_size=8), st.lists(st.floats(0, 1), min_size=1, max_size=8))
def test_soft_dtw_tends_to_dtw_and_divergence_is_nonnegative(x, y):
    tx, ty = torch.tensor([x], dtype=torch.float64), torch.tensor([y], dtype=torch.float64)
    assert float(soft_dtw(tx, ty, 1e-4)) == pytest.approx(naive_dtw(x, y), abs=1e-2)
    assert float(soft_dtw_divergence(tx, ty, 0.1)) >= -1e-9
    assert float(soft_dtw_divergence(tx, tx, 0.1)) == pytest.approx(0.0, abs=1e-9)


def test_soft_dtw_rewards_a_one_frame_shift_over_a_miss():
    target = torch.tensor([[0, 0, 1, 0, 0, 0, 0, 0.0]])
    shifted = torch.tensor([[0, 0, 0, 1, 0, 0, 0, 0.0]])
    missed = torch.zeros(1, 8)
    assert float(soft_dtw_divergence(shifted, target, 0.1)) < float(soft_dtw_divergence(missed, target, 0.1))


def _inputs(cfg, b=2, seed=0):
    g = torch.Generator().manual_seed(seed)
    w = cfg.window
    return (torch.randint(0, 16, (b, cfg.past), generator=g), torch.randn(b, w, 56, generator=g),
            torch.randn(b, w * cfg.audio_rows_per_frame, cfg.audio_bins, generator=g),
            torch.ones(b, w, dtype=torch.bool))


@pytest.mark.parametrize("span, changes", [("concurrent", True), ("past", False)])
def test_speaker_span_decides_whether_concurrent_frames_are_read(span, changes):
    cfg = predictor_preset("tiny", speaker_span=span, **MICRO)
    model = SFMSPredictor(cfg, 56, 16).eval()
    for block in model.fusion:
        block.alpha.data.fill_(0.5)
    past, spk, aud, valid = _inputs(cfg)
    spk2, aud2 = spk.clone(), aud.clone()
    spk2[:, cfg.past:] += 5.0
    aud2[:, cfg.past * cfg.audio_rows_per_frame:] += 5.0
    with torch.no_grad():
        same = torch.equal(model(past, spk, aud, valid), model(past, spk2, aud2, valid))
    assert same != changes


def test_invalid_speaker_frames_are_not_read_and_empty_windows_stay_finite():
    cfg = predictor_preset("tiny", **MICRO)
    model = SFMSPredictor(cfg, 56, 16).eval()
    past, spk, aud, valid = _inputs(cfg)
    valid[:, :10] = False
    spk2, aud2 = spk.clone(), aud.clone()
    spk2[:, :10] = 99.0
    aud2[:, :40] = 99.0
    with torch.no_grad():
        torch.testing.assert_close(model(past, spk, aud, valid), model(past, spk2, aud2, valid))
        assert torch.isfinite(model(past, spk, aud, torch.zeros_like(valid))).all()


def test_predictor_training_lowers_the_loss():
    cfg = predictor_preset("tiny", steps=40, batch=16, lr=3e-3, **MICRO)
    tok = SFMSTokenizer(tokenizer_preset("tiny", width=32, heads=2, ffn=64, pe_dim=8)).eval()
    raw = directed_clips(make_clips("train", 3, duration_s=8.0), cfg)
    rows = np.concatenate([r[3] for r in raw])
    clips = normalise_directed(raw, np.zeros(56, np.float32), np.ones(56, np.float32), rows.mean(0), rows.std(0))
    model, history = fit_predictor(cfg, tok, clips[:4], clips[4:], audio_mean=rows.mean(0), audio_std=rows.std(0),
                                   seed=0, val_windows=32, val_every=20, progress=False)
    first = np.mean([s["loss"] for s in history["steps"][:3]])
    last = np.mean([s["loss"] for s in history["steps"][-3:]])
    assert last < 0.7 * first
    assert {"ce", "unigram_ce"} <= set(history["val"][-1])
    assert model.predictor.audio_mean.shape == (8,)


def test_training_batch_has_aligned_windows_and_neutral_prefix():
    cfg = predictor_preset("tiny", neutral_prob=1.0, pre_start_prob=0.0, **MICRO)
    raw = directed_clips(make_clips("train", 1, duration_s=6.0), cfg)
    clips = normalise_directed(raw, np.zeros(56, np.float32), np.ones(56, np.float32), np.zeros(8, np.float32),
                               np.ones(8, np.float32))
    batch = sample_predictor_batch(clips, cfg, 8, np.random.default_rng(0))
    assert batch.listener.shape == (8, 48, 56) and batch.audio.shape == (8, 192, 8)
    assert (batch.listener[:, 0] == 0).all()  # the oldest past frame is always neutral at p = 1
    assert (batch.listener[:, 40:] != 0).any(axis=(1, 2)).all()  # the future is never blanked
    assert batch.valid.all()
