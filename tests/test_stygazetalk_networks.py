"""StyGazeTalk networks on random tensors: NT-Xent, style encoder, generator, losses, one training step."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
import torch

from models.stygazetalk.config import GENERATORS, STYLE_ENCODERS, get_generator_config, get_style_config
from models.stygazetalk.generator import MotionGenerator
from models.stygazetalk.style_encoder import StyleEncoder, nt_xent
from models.stygazetalk.data import Segment
from models.stygazetalk.system import StyGazeTalkSystem
from models.stygazetalk.train_generator import _val_loss, banks_for, generator_loss, train_generator, window_loss

torch.set_num_threads(1)
M, N, F_AUDIO = 50, 25, 40


def _hand_nt_xent(a: list[list[float]], b: list[list[float]], tau: float) -> float:
    """Independent reference: plain-Python NT-Xent, mean over the 2B views."""
    z = [list(v) for v in a + b]
    n = len(a)

    def cos(u, v):
        return sum(x * y for x, y in zip(u, v)) / (math.sqrt(sum(x * x for x in u)) * math.sqrt(sum(y * y for y in v)))

    total = 0.0
    for i in range(2 * n):
        pos = (i + n) % (2 * n)
        denom = sum(math.exp(cos(z[i], z[k]) / tau) for k in range(2 * n) if k != i)
        total += -math.log(math.exp(cos(z[i], z[pos]) / tau) / denom)
    return total / (2 * n)


def test_nt_xent_orthonormal_pairs_by_hand():
    # z = [e1, e2, e1, e2], tau = 1: every view's positive has cos 1, the two others cos 0:
    # loss = -log(e / (e + 2)) = log(1 + 2/e) for each of the 4 views.
    a = torch.tensor([[1.0, 0.0], [0.0, 1.0]])
    loss = nt_xent(a, a.clone(), temperature=1.0)
    assert loss.item() == pytest.approx(math.log(1.0 + 2.0 / math.e), abs=1e-6)


def test_nt_xent_single_pair_has_zero_loss():
    # B = 1: each view's only candidate is its positive.
    loss = nt_xent(torch.tensor([[1.0, 0.0]]), torch.tensor([[0.0, 1.0]]), temperature=0.1)
    assert loss.item() == pytest.approx(0.0, abs=1e-7)


def test_nt_xent_matches_plain_python_reference_and_sum_form():
    a = [[1.0, 0.0, 2.0], [1.0, 1.0, 0.0], [0.0, -1.0, 0.5]]
    b = [[1.0, 1.0, 1.0], [0.0, 1.0, 0.0], [0.3, -1.0, 0.0]]
    ta, tb = torch.tensor(a, dtype=torch.float64), torch.tensor(b, dtype=torch.float64)
    assert nt_xent(ta, tb, 0.5).item() == pytest.approx(_hand_nt_xent(a, b, 0.5), rel=1e-12)
    assert nt_xent(ta, tb, 0.5, reduction="sum").item() == pytest.approx(6 * _hand_nt_xent(a, b, 0.5), rel=1e-12)
    # the loss is invariant to the embeddings' scale (cosine similarity)
    assert nt_xent(3 * ta, 0.5 * tb, 0.5).item() == pytest.approx(nt_xent(ta, tb, 0.5).item(), rel=1e-12)


def test_nt_xent_rejects_mismatched_shapes():
    with pytest.raises(ValueError, match="one shape"):
        nt_xent(torch.zeros(2, 3), torch.zeros(3, 3), 0.1)


def test_style_encoder_shape_and_order_sensitivity():
    torch.manual_seed(0)
    se = StyleEncoder(get_style_config("tiny-se32")).eval()
    x = torch.randn(4, M, 7)
    s = se(x)
    assert s.shape == (4, 32)
    # per-position encoding (D14): reversing time changes the style vector (DiffPoseTalk's constant-offset
    # encoding would make the mean-pooled encoder order-blind)
    assert not torch.allclose(se(torch.flip(x, dims=[1])), s, atol=1e-4)


def _generator(name: str = "tiny-se64", **over) -> MotionGenerator:
    torch.manual_seed(0)
    return MotionGenerator(replace(get_generator_config(name), **over), F_AUDIO).eval()


def _inputs(batch: int = 3, seed: int = 0):
    g = torch.Generator().manual_seed(seed)
    return (torch.randn(batch, M, F_AUDIO, generator=g), torch.randn(batch, M, 7, generator=g),
            torch.randn(batch, 64, generator=g))


def test_learned_initial_states_receive_gradients_and_matter():
    gen = _generator()
    audio, motion, style = _inputs()
    loss = gen(audio, motion, style).pow(2).mean()
    loss.backward()
    for p in (gen.core.h0, gen.core.c0):
        assert p.requires_grad and p.grad is not None and p.grad.abs().sum() > 0
    with torch.no_grad():
        before = gen(audio, motion, style)
        gen.core.h0.add_(0.5)
        assert not torch.allclose(gen(audio, motion, style), before)


@pytest.mark.parametrize("name", ["tiny-se64", "tiny-tfm-se64", "tiny-base"])
def test_step_i_output_depends_only_on_steps_up_to_i(name):
    gen = _generator(name)
    audio, motion, style = _inputs()
    style = style if gen.cfg.style else None
    with torch.no_grad():
        ref = gen(audio, motion, style)
        k = 30
        audio2, motion2 = audio.clone(), motion.clone()
        audio2[:, k:] += 5.0
        motion2[:, k:] -= 5.0
        out = gen(audio2, motion2, style)
    assert torch.equal(out[:, :k], ref[:, :k])
    assert not torch.allclose(out[:, k:], ref[:, k:])


@pytest.mark.parametrize("name", ["tiny-se64", "tiny-tfm-se64"])
def test_generate_block_warms_up_on_known_frames_then_feeds_back_its_outputs(name):
    gen = _generator(name)
    audio, motion, style = _inputs()
    w = gen.cfg.warmup
    with torch.no_grad():
        block = gen.generate_block(audio, motion[:, :w + 1], style)
        assert block.shape == (3, N, 7)
        # the first new frame is the teacher-forced output of step W (only known inputs before it)
        assert torch.allclose(block[:, 0], gen(audio, motion, style)[:, w], atol=1e-6)
        # feeding the block's own frames as motion inputs reproduces it (autoregression, one-frame lag)
        fed = torch.cat([motion[:, :w + 1], block[:, :-1]], dim=1)
        assert torch.allclose(gen(audio, fed, style)[:, w:], block, atol=1e-5)


def test_sampled_decoding_feeds_back_the_drawn_frames():
    gen = _generator()
    audio, motion, style = _inputs()
    w = gen.cfg.warmup
    with torch.no_grad():
        block = gen.generate_block(audio, motion[:, :w + 1], style, draw=lambda mean: mean + 1.0)
        assert torch.allclose(block[:, 0], gen(audio, motion, style)[:, w] + 1.0, atol=1e-6)
        fed = torch.cat([motion[:, :w + 1], block[:, :-1]], dim=1)
        assert torch.allclose(gen(audio, fed, style)[:, w:] + 1.0, block, atol=1e-5)
        # teacher forcing ignores the draw
        assert torch.equal(gen(audio, motion, style, draw=lambda mean: mean + 1.0), gen(audio, motion, style))


def test_base_variant_has_no_style_input_and_style_variants_require_one():
    base = _generator("tiny-base")
    assert base.core.lstm.input_size == 2 * base.cfg.d
    se = _generator("tiny-se64")
    assert se.core.lstm.input_size == 2 * se.cfg.d + 64
    audio, motion, _ = _inputs()
    with pytest.raises(ValueError, match="style vector"):
        se(audio, motion, None)


def test_residual_output_adds_the_motion_input():
    gen = _generator(residual_output=True)
    absolute = _generator(residual_output=False)
    audio, motion, style = _inputs()
    with torch.no_grad():
        assert torch.allclose(gen(audio, motion, style), absolute(audio, motion, style) + motion, atol=1e-6)


def test_generator_loss_by_hand():
    pred = torch.tensor([[[1.0], [3.0]]])  # (B=1, T=2, D=1)
    target = torch.tensor([[[0.0], [1.0]]])
    prev = torch.tensor([[[0.0]]])
    loss, mse, vel = generator_loss(pred, target, prev, lam=0.25)
    # mse = (1 + 4)/2; velocities: pred [1, 2], target [0, 1] -> errors 1, 1 -> vel = 1
    assert mse.item() == pytest.approx(2.5)
    assert vel.item() == pytest.approx(1.0)
    assert loss.item() == pytest.approx(0.25 * 2.5 + 0.75 * 1.0)
    # both difference sequences start from the ground-truth predecessor (D20): a constant offset c of
    # the prediction shows only in the first difference, so vel = c^2 / T
    _, _, vel_offset = generator_loss(target + 2.0, target, prev, lam=0.5)
    assert vel_offset.item() == pytest.approx(4.0 / 2)
    assert generator_loss(target, target, prev, lam=0.3)[0].item() == 0.0


def test_a_training_step_lowers_the_loss():
    gen = _generator()
    gen.train()
    audio, motion, style = _inputs(batch=8)
    target = torch.roll(motion, -1, dims=1)
    opt = torch.optim.Adam(gen.parameters(), lr=1e-2)

    def loss_now():
        return generator_loss(gen(audio, motion, style), target, motion[:, :1], lam=0.5)[0]

    before = loss_now()
    for _ in range(3):
        loss = loss_now()
        opt.zero_grad()
        loss.backward()
        opt.step()
    assert loss_now().item() < before.item()


def test_a_contrastive_step_lowers_nt_xent():
    torch.manual_seed(0)
    se = StyleEncoder(get_style_config("tiny-se32"))
    a = torch.randn(8, M, 7)
    b = a + 0.1 * torch.randn(8, M, 7)
    opt = torch.optim.Adam(se.parameters(), lr=1e-3)
    before = nt_xent(se(a), se(b), 0.1).item()
    for _ in range(3):
        loss = nt_xent(se(a), se(b), 0.1)
        opt.zero_grad()
        loss.backward()
        opt.step()
    assert nt_xent(se(a), se(b), 0.1).item() < before


def test_every_preset_validates_and_records_its_decisions():
    for cfg in GENERATORS.values():
        d = cfg.to_dict()
        for field in ("alignment", "window", "horizon", "lam", "style_input", "loss_outputs", "rollout_prob",
                      "window_local_audio", "audio_features", "seed_window", "freeze_style_encoder", "seed"):
            assert field in d
        assert cfg.validate() is cfg
    assert get_generator_config("tiny-se64-vel").lam == 0.5 and get_generator_config("tiny-se64").lam == 1.0
    assert get_generator_config("base-tfm-se64").backbone == "transformer"
    assert not get_generator_config("base-base").style
    assert {c.d_s for c in STYLE_ENCODERS.values()} == {32, 64}


def test_parameter_counts_match_the_spec_hand_counts():
    def count(module):
        return sum(p.numel() for p in module.parameters())

    tiny = MotionGenerator(get_generator_config("tiny-se32"), 40)
    assert count(tiny) == 77_031  # spec §2.13: tiny generator with d_s = 32, log-mel 40
    # spec §2.13 counts Linear(7 -> d_s); the presets read 14 inputs (D47: + velocities), 7 * d_s more
    plain = {"input_features": "angles"}
    assert count(StyleEncoder(replace(get_style_config("tiny-se32"), **plain))) == 25_664
    assert count(StyleEncoder(replace(get_style_config("tiny-se64"), **plain))) == 100_480
    assert count(StyleEncoder(replace(get_style_config("base-se64"), **plain))) == 200_448
    assert count(StyleEncoder(get_style_config("tiny-se64"))) == 100_480 + 7 * 64
    base = MotionGenerator(get_generator_config("base-se64"), 768)
    assert count(base.core) + count(base.head) == 1_644_544 + 1_536 + 1_799
    assert np.isclose(count(base), 1.75e6, rtol=0.01)


def test_initial_weights_depend_only_on_the_config_seed():
    from models.stygazetalk.system import StyGazeTalkSystem

    cfg, se_cfg = get_generator_config("tiny-se64"), get_style_config("tiny-se64")
    torch.manual_seed(1)
    a = StyGazeTalkSystem(cfg, se_cfg).state_dict()
    torch.manual_seed(2)
    torch.randn(10)
    b = StyGazeTalkSystem(cfg, se_cfg).state_dict()
    c = StyGazeTalkSystem(replace(cfg, seed=1), se_cfg).state_dict()
    assert all(torch.equal(a[k], b[k]) for k in a)
    assert not torch.equal(a["generator.head.weight"], c["generator.head.weight"])


def test_recorded_decisions_without_an_alternative_are_rejected_not_ignored():
    from dyadbench.errors import ConfigError

    with pytest.raises(ConfigError, match="window_local_audio"):
        replace(get_generator_config("tiny-se64"), window_local_audio=False).validate()
    with pytest.raises(ConfigError, match="positional_encoding"):
        StyleEncoder(replace(get_style_config("tiny-se64"), positional_encoding="learned"))
    with pytest.raises(ConfigError, match="horizon"):
        replace(get_generator_config("tiny-se64"), horizon=60).validate()


def test_nt_xent_labels_drop_same_label_negatives_by_hand():
    a = [[1.0, 0.0], [0.6, 0.8], [0.0, 1.0]]
    b = [[0.8, 0.6], [0.0, 1.0], [1.0, 0.0]]
    ta, tb = torch.tensor(a, dtype=torch.float64), torch.tensor(b, dtype=torch.float64)
    labels = torch.tensor([0, 0, 1])
    z = [np.asarray(v) / np.linalg.norm(v) for v in a + b]
    views, partner, tau = [0, 0, 1, 0, 0, 1], [3, 4, 5, 0, 1, 2], 0.5
    total = 0.0
    for i in range(6):  # denominator: the partner and every view of another label
        keep = [k for k in range(6) if k != i and (k == partner[i] or views[k] != views[i])]
        logits = {k: float(z[i] @ z[k]) / tau for k in keep}
        total += -(logits[partner[i]] - math.log(sum(math.exp(v) for v in logits.values())))
    assert nt_xent(ta, tb, tau, labels=labels).item() == pytest.approx(total / 6, rel=1e-12)
    # all labels distinct: the plain loss
    assert nt_xent(ta, tb, tau, labels=torch.arange(3)).item() == pytest.approx(nt_xent(ta, tb, tau).item(), rel=1e-12)
    with pytest.raises(ValueError, match="labels"):
        nt_xent(ta, tb, tau, labels=torch.zeros(2))


def test_centred_velocity_input_ignores_a_constant_pose_offset():
    cfg = replace(get_style_config("tiny-se64"), input_features="centred+velocity")
    torch.manual_seed(0)
    se = StyleEncoder(cfg).eval()
    x = torch.randn(3, M, 7)
    feats = se.features(x)
    assert feats.shape == (3, M, 14) and torch.allclose(feats[:, 0, 7:], torch.zeros(3, 7))
    with torch.no_grad():
        assert torch.allclose(se(x), se(x + torch.randn(3, 1, 7) * 5), atol=1e-5)
        plain = StyleEncoder(replace(cfg, input_features="angles")).eval()
        assert not torch.allclose(plain(x), plain(x + 5.0), atol=1e-3)


def test_val_mse_selection_keeps_the_weights_with_the_lowest_validation_mse():
    cfg = replace(get_generator_config("tiny-base"), lam=0.5, steps=4, val_every=1, batch=4,
                  checkpoint_selection="val-mse")
    rng = np.random.default_rng(0)
    segs = [Segment(f"s{i}", "spk", 0, rng.normal(size=(200, 7)).astype(np.float32),
                    0.1 * rng.normal(size=200 * 640).astype(np.float32)) for i in range(2)]
    system = StyGazeTalkSystem(cfg, None)
    log = train_generator(system, segs[:1], segs[1:], progress=False)
    _, val_bank = banks_for(system, segs[:1], segs[1:])
    kept = _val_loss(system, val_bank, cfg.batch)
    assert log.best_val == min(log.val_loss) and kept == pytest.approx(log.best_val, rel=1e-6)
    with torch.no_grad():  # the tracked criterion is L_mse alone, not L_gen = 0.5 L_mse + 0.5 L_vel
        loss, mse, _ = window_loss(system, torch.from_numpy(val_bank.motion), torch.from_numpy(val_bank.audio))
    assert kept == pytest.approx(mse.item(), rel=1e-5) and kept != pytest.approx(loss.item(), rel=1e-3)
