"""TIMAR network: token layout, turn-level causal and band attention, exact caches, diffusion, training."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from models.timar.config import preset
from models.timar.diffusion import GaussianDiffusion, cosine_betas, space_timesteps
from models.timar.head import DiffusionHead
from models.timar.model import TimarModel, agent_motion_slice, count_parameters

MICRO = dict(token_dim=16, dim=16, heads=2, depth=2, head_width=16, frames_per_turn=5, samples_per_turn=3200,
             max_turns=4)
F = MICRO["frames_per_turn"]


def micro_model(variant: str, seed: int = 0) -> TimarModel:
    torch.manual_seed(seed)
    model = TimarModel(preset("tiny", variant, **MICRO)).eval()
    with torch.no_grad():  # the head starts at zero output; give it weights so outputs depend on inputs
        for p in model.head.parameters():
            p.add_(torch.randn_like(p) * 0.1)
    return model


def random_inputs(batch: int, turns: int, seed: int = 1) -> dict[str, torch.Tensor]:
    g = torch.Generator().manual_seed(seed)
    return {"user_speech": torch.randn(batch, turns, F, 40, generator=g),
            "user_motion": torch.randn(batch, turns, F, 56, generator=g) * 0.3,
            "agent_speech": torch.randn(batch, turns, F, 40, generator=g)}


def test_large_has_the_papers_parameter_count():
    assert count_parameters(preset("large")) == pytest.approx(428e6, rel=0.01)


def test_space_timesteps_keeps_the_published_sampling_steps():
    assert space_timesteps(1000, 5) == [0, 250, 500, 749, 999]


def _cosine_alpha_bar(u: float) -> float:
    """Nichol & Dhariwal (2021) eq. 17: ᾱ(u) = f(u) / f(0), f(u) = cos²((u + 0.008) / 1.008 · π / 2), u = t / T."""
    f = lambda v: math.cos((v + 0.008) / 1.008 * math.pi / 2) ** 2  # noqa: E731
    return f(u) / f(0)


def test_respaced_process_keeps_alpha_bar_at_kept_steps():
    # step t of the 1000-step process has noised t + 1 times: ᾱ_t = ᾱ((t + 1) / 1000); the last step's β is
    # capped at 0.999 (the closed form gives 1 - cos²(π/2) / ... = 1), so ᾱ_999 = 0.001 ᾱ(999 / 1000)
    kept = [0, 250, 500, 749, 999]  # round(i · 999 / 4), i = 0..4
    expected = [_cosine_alpha_bar((t + 1) / 1000) for t in kept[:-1]] + [0.001 * _cosine_alpha_bar(0.999)]
    spaced = GaussianDiffusion.respaced(1000, 5)
    np.testing.assert_allclose(spaced.alphas_cumprod, expected, rtol=1e-9)
    ratios = np.array(expected) / np.array([1.0, *expected[:-1]])
    np.testing.assert_allclose(spaced.betas, 1 - ratios, rtol=1e-9)
    assert spaced.timestep_map.tolist() == kept


def test_cosine_schedule_is_increasing_and_capped():
    betas = cosine_betas(1000)
    assert np.all(np.diff(betas) >= 0) and betas.max() <= 0.999 and betas.min() > 0


def test_vb_term_is_non_negative_and_zero_for_the_true_posterior():
    d = GaussianDiffusion.training(1000)
    g = torch.Generator().manual_seed(0)
    x0, noise = torch.randn(64, 56, generator=g) * 0.1, torch.randn(64, 56, generator=g)
    t = torch.randint(1, 1000, (64,), generator=g)
    xt = d.q_sample(x0, t, noise)
    exact = torch.cat([x0, -torch.ones_like(x0)], dim=-1)  # v = -1: log variance = posterior's
    assert d.vb_term(exact, x0, xt, t).abs().max() < 1e-4
    wrong = torch.cat([x0 + 0.5, torch.zeros_like(x0)], dim=-1)
    assert (d.vb_term(wrong, x0, xt, t) >= 0).all()


def test_turn_tokens_interleave_specials_and_mask_agent_motion():
    model = micro_model("faithful")
    tokens = model.turn_tokens(**random_inputs(2, 3))
    assert tokens.shape == (2, 3, 4 * F + 10, 16)
    specials = [0, 1, 2 + F, 3 + F, 4 + 2 * F, 5 + 2 * F, 6 + 3 * F, 7 + 3 * F, 8 + 4 * F, 9 + 4 * F]
    torch.testing.assert_close(tokens[1, 2, specials], model.special_tokens.detach())
    agent = tokens[:, :, agent_motion_slice(F)]
    torch.testing.assert_close(agent, model.mask_token.detach().expand_as(agent))


def test_null_tokens_replace_exactly_the_dropped_user_tokens():
    model = micro_model("faithful")
    drop = torch.zeros(1, 2, 2 * F, dtype=torch.bool)
    drop[0, 1, 0] = drop[0, 0, F + 2] = True
    tokens = model.turn_tokens(**random_inputs(1, 2), user_null=drop)
    null = model.null_token.detach()
    assert torch.equal(tokens[0, 1, 2], null) and torch.equal(tokens[0, 0, 4 + F + 2], null)
    assert (tokens == null).all(-1).sum() == 2


@pytest.mark.parametrize("variant,band", [("faithful", None), ("stream", 3)])
def test_changing_a_later_turn_never_changes_earlier_turns(variant, band):
    model = micro_model(variant)
    inputs = random_inputs(1, 4)
    base = model.encode(model.turn_tokens(**inputs), band)
    inputs["user_motion"][:, 2:] += 1.0
    changed = model.encode(model.turn_tokens(**inputs), band)
    assert torch.equal(base[:, :2], changed[:, :2])
    assert not torch.allclose(base[:, 2:], changed[:, 2:])


def test_faithful_positions_depend_on_the_window_start():
    model = micro_model("faithful")
    tokens = model.turn_tokens(**random_inputs(1, 3))
    alone = model.encode(tokens[:, 2:])
    in_window = model.encode(tokens[:, 1:])[:, 1:]
    assert not torch.allclose(alone, in_window)  # same turn, other window position: other states


def test_stream_band_limits_the_receptive_field_to_depth_times_band():
    model = micro_model("stream")  # depth 2, band 1: turn 3 sees turns 1..3 only
    inputs = random_inputs(1, 4)
    base = model.encode(model.turn_tokens(**inputs), 1)
    far = {k: v.clone() for k, v in inputs.items()}
    far["agent_speech"][:, 0] += 5.0
    assert torch.equal(model.encode(model.turn_tokens(**far), 1)[:, 3], base[:, 3])
    near = {k: v.clone() for k, v in inputs.items()}
    near["agent_speech"][:, 1] += 5.0
    assert not torch.allclose(model.encode(model.turn_tokens(**near), 1)[:, 3], base[:, 3])


@pytest.mark.parametrize("variant,band", [("faithful", None), ("stream", 0), ("stream", 2), ("stream", 3)])
def test_cached_turn_encoding_equals_full_encoding(variant, band):
    model = micro_model(variant)
    tokens = model.turn_tokens(**random_inputs(2, 4))
    full = model.encode(tokens, band)
    past = [[] for _ in model.blocks]
    for i in range(4):
        cond, kv = model.encode_next_turn(tokens[:, i:i + 1], past)
        torch.testing.assert_close(cond[:, 0], full[:, i], atol=1e-5, rtol=0)
        for layer, pair in enumerate(kv):
            past[layer] = (past[layer] + [pair])[-band:] if band is not None else past[layer] + [pair]
            if band == 0:
                past[layer] = []


def test_guidance_scale_one_on_two_branches_equals_the_conditional_branch():
    model = micro_model("faithful")
    cond = torch.randn(2, F, 16)
    single = model.sample_frames(cond[:1], torch.Generator().manual_seed(3))
    guided = model.sample_frames(cond, torch.Generator().manual_seed(3), cfg_scale=1.0)
    torch.testing.assert_close(single, guided, atol=1e-5, rtol=0)
    stronger = model.sample_frames(cond, torch.Generator().manual_seed(3), cfg_scale=3.0)
    assert not torch.allclose(single, stronger)


def test_training_mask_count_follows_the_truncated_ratio():
    model = micro_model("faithful")
    torch.manual_seed(0)
    for _ in range(20):
        mask = model.training_mask(3, 200)
        counts = mask.sum(1)
        assert (counts == counts[0]).all()
        assert math.ceil(200 * 0.7) <= counts[0] <= 200


@pytest.mark.parametrize("variant", ["faithful", "stream"])
def test_training_steps_reduce_the_loss(variant):
    model = micro_model(variant).train()
    inputs = {k: v.reshape(4, 4 * F, -1) for k, v in random_inputs(4, 4).items()}
    g = torch.Generator().manual_seed(2)
    agent = torch.cumsum(torch.randn(4, 4 * F, 56, generator=g) * 0.05, 1)

    def loss_at_fixed_seed() -> float:
        torch.manual_seed(123)
        with torch.no_grad():
            return model(**inputs, agent_motion=agent).item()

    before = loss_at_fixed_seed()
    opt = torch.optim.AdamW(model.parameters(), lr=3e-3)
    torch.manual_seed(0)
    for _ in range(25):
        loss = model(**inputs, agent_motion=agent)
        opt.zero_grad()
        loss.backward()
        opt.step()
    assert loss_at_fixed_seed() < 0.8 * before


def test_sampling_clamps_the_variance_interpolation_to_its_range():
    d = GaussianDiffusion.respaced(1000, 5)
    xt, t = torch.zeros(3, 56), torch.full((3,), 1)
    x0 = torch.zeros(3, 56)
    beyond = d.p_mean_logvar(torch.cat([x0, torch.full((3, 56), 5.0)], -1), xt, t, clamp_variance=True)[1]
    edge = d.p_mean_logvar(torch.cat([x0, torch.ones(3, 56)], -1), xt, t)[1]
    torch.testing.assert_close(beyond, edge)  # clamped v = 1: log variance = log beta_t
    torch.testing.assert_close(edge, torch.full_like(edge, math.log(d.betas[1])))
    free = d.p_mean_logvar(torch.cat([x0, torch.full((3, 56), 5.0)], -1), xt, t)[1]
    assert (free > edge).all()


def test_precomputed_step_modulations_equal_the_per_step_head():
    """Sampling computes every step's modulation in one pass; each step must equal the head's own call."""
    torch.manual_seed(0)
    head = DiffusionHead(56, 32, 48, 2)
    for p in head.parameters():  # modulations start at zero: give them values
        torch.nn.init.normal_(p, std=0.2)
    x, cond = torch.randn(7, 56), head.cond_embed(torch.randn(7, 32))
    timesteps = torch.tensor([0, 250, 500, 749, 999])
    modulation = head.modulation(head.time_embed(timesteps)[:, None] + cond)
    for i, t in enumerate(timesteps):
        expected = head.denoise(x, torch.full((7,), int(t)), cond)
        torch.testing.assert_close(head.denoise_modulated(x, modulation.at(i)), expected, rtol=0, atol=1e-5)
