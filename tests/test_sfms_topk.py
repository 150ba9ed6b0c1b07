"""SFMS keyframe selection: Algorithm 1 (Gumbel soft top-k, straight-through) and the fixed masks."""

import numpy as np
import pytest
import torch
from hypothesis import given, settings, strategies as st

from models.sfms.topk import gumbel_soft_topk, hard_topk, relaxed_topk, static_mask


@settings(max_examples=25, deadline=None)
@given(t=st.integers(2, 64), data=st.data(), seed=st.integers(0, 2**16), tau=st.floats(0.05, 2.0))
def test_forward_mask_has_exactly_k_ones_and_r_equals_hard(t, data, seed, tau):
    k = data.draw(st.integers(1, t))
    g = torch.Generator().manual_seed(seed)
    s = torch.randn(3, t, generator=g)
    r, hard, hot_k = gumbel_soft_topk(s, k, tau, generator=g)
    assert torch.equal(hard.sum(-1), torch.full((3,), float(k)))
    assert set(hard.unique().tolist()) <= {0.0, 1.0}
    assert torch.equal(r, hard)  # exact, not approximate: the ST term is zero in the forward pass
    torch.testing.assert_close(hot_k.sum(-1), torch.full((3,), float(k)), rtol=0, atol=1e-4)


def test_gradient_reaches_logits_through_straight_through():
    s = torch.randn(4, 48, requires_grad=True)
    r, _, _ = gumbel_soft_topk(s, 7, 1.0, generator=torch.Generator().manual_seed(0))
    (r * torch.linspace(-1, 1, 48)).sum().backward()
    assert torch.isfinite(s.grad).all()
    assert s.grad.abs().sum() > 0


def test_same_seed_same_mask_different_seed_differs():
    s = torch.zeros(8, 48)
    masks = [gumbel_soft_topk(s, 7, 1.0, generator=torch.Generator().manual_seed(seed))[1] for seed in (1, 1, 2)]
    assert torch.equal(masks[0], masks[1])
    assert not torch.equal(masks[0], masks[2])


def test_small_temperature_makes_hotk_nearly_k_hot():
    s = torch.randn(16, 48, generator=torch.Generator().manual_seed(3)) * 3
    gaps = []
    for tau in (1.0, 0.1, 0.01):
        _, hard, hot_k = gumbel_soft_topk(s, 7, tau, generator=torch.Generator().manual_seed(0))
        gaps.append(float((hot_k - hard).abs().mean()))
    assert gaps[0] > gaps[1] > gaps[2]
    assert gaps[2] < 0.01


def test_relaxed_topk_by_hand_for_k1_is_softmax():
    s = torch.tensor([[0.0, 1.0, 2.0]])
    torch.testing.assert_close(relaxed_topk(s, 1, 0.5), torch.softmax(s / 0.5, -1))


def test_relaxed_entries_can_exceed_one_without_noise_at_tau_one():
    hot_k = relaxed_topk(torch.randn(1, 48, generator=torch.Generator().manual_seed(0)) * 3, 7, 1.0)
    assert float(hot_k.sum()) == pytest.approx(7.0, abs=1e-4)


def test_hard_topk_breaks_ties_to_lower_index():
    assert hard_topk(torch.zeros(1, 6), 2).tolist() == [[1, 1, 0, 0, 0, 0]]
    assert hard_topk(torch.tensor([[0.0, 5, 5, 1, 5]]), 2).tolist() == [[0, 1, 1, 0, 0]]


@pytest.mark.parametrize("k, expected", [(3, [0, 16, 32]), (7, [0, 6, 12, 18, 24, 30, 36]),
                                         (10, [0, 4, 8, 12, 16, 20, 24, 28, 32, 36])])
def test_static_mask_is_uniform_every_floor_t_over_k(k, expected):
    mask = static_mask(2, 48, k)
    assert np.flatnonzero(mask[0].numpy()).tolist() == expected
    assert torch.equal(mask[0], mask[1])


def test_bad_k_is_rejected():
    with pytest.raises(ValueError, match="k must be"):
        gumbel_soft_topk(torch.zeros(1, 5), 6, 1.0)


def _picks(mask_row: torch.Tensor) -> np.ndarray:
    return np.flatnonzero(mask_row.numpy())


@settings(max_examples=40, deadline=None)
@given(t=st.integers(2, 64), data=st.data(), seed=st.integers(0, 2**16))
def test_radius_zero_is_plain_topk_with_ties_to_the_lower_index(t, data, seed):
    k = data.draw(st.integers(1, t))
    s = torch.randint(0, 4, (3, t), generator=torch.Generator().manual_seed(seed)).float()  # many ties
    order = torch.sort(s, dim=-1, descending=True, stable=True).indices[..., :k]
    assert torch.equal(hard_topk(s, k, radius=0), torch.zeros_like(s).scatter(-1, order, 1.0))


@settings(max_examples=40, deadline=None)
@given(t=st.integers(8, 64), data=st.data(), seed=st.integers(0, 2**16))
def test_suppression_keeps_picks_more_than_radius_apart(t, data, seed):
    radius = data.draw(st.integers(1, 8))
    k_max = max(1, (t - 1) // (2 * radius + 1) + 1)  # (k − 1)(2r + 1) < T: greedy never runs out
    k = data.draw(st.integers(1, k_max))
    s = torch.randn(4, t, generator=torch.Generator().manual_seed(seed))
    hard = hard_topk(s, k, radius)
    assert torch.equal(hard.sum(-1), torch.full((4,), float(k)))
    for row in hard:
        assert np.all(np.diff(_picks(row)) > radius)


def test_suppression_by_hand_and_when_the_window_runs_out():
    s = torch.tensor([[0.0, 9, 8, 1, 7, 0]])
    assert _picks(hard_topk(s, 2, radius=0)[0]).tolist() == [1, 2]
    assert _picks(hard_topk(s, 2, radius=1)[0]).tolist() == [1, 4]  # 2 is next to 1
    assert _picks(hard_topk(s, 3, radius=2)[0]).tolist() == [1, 2, 4]  # 4 excludes all; then best unpicked
    assert float(hard_topk(s, 6, radius=3).sum()) == 6.0


def test_suppressed_relaxation_sums_to_k_and_tends_to_the_suppressed_hard_mask():
    g = torch.Generator().manual_seed(5)
    # scores 0.4 apart (40 nats at τ = 0.01) and spanning less than the −log ε = 23 of a suppression
    s = torch.stack([torch.randperm(48, generator=g) for _ in range(16)]).float() * 0.4
    for radius in (1, 3):
        hot_k = relaxed_topk(s, 7, 1.0, radius=radius)
        torch.testing.assert_close(hot_k.sum(-1), torch.full((16,), 7.0), rtol=0, atol=1e-4)
        torch.testing.assert_close(relaxed_topk(s, 7, 1e-2, radius=radius), hard_topk(s, 7, radius), rtol=0, atol=1e-3)


def test_suppressed_gumbel_topk_is_exact_in_the_forward_pass_and_passes_gradients():
    s = torch.randn(4, 48, requires_grad=True)
    r, hard, _ = gumbel_soft_topk(s, 7, 0.5, generator=torch.Generator().manual_seed(0), radius=3)
    assert torch.equal(r, hard)
    for row in hard:
        assert np.all(np.diff(_picks(row.detach())) > 3)
    (r * torch.linspace(-1, 1, 48)).sum().backward()
    assert torch.isfinite(s.grad).all() and s.grad.abs().sum() > 0
