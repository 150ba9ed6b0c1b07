"""SFMS keyframe quantisers: FSQ grid round trips and straight-through; VQ nearest code and losses."""

import pytest
import torch
from hypothesis import given, settings, strategies as st

from models.sfms.fsq import FSQ
from models.sfms.vq import VQ


@pytest.mark.parametrize("levels", [(8, 6, 5), (5, 3), (8, 5, 5, 5), (4, 4, 4, 4)])
def test_fsq_index_code_index_round_trips_every_code(levels):
    fsq = FSQ(levels, 16)
    n = 1
    for level in levels:
        n *= level
    assert fsq.n_codes == n
    idx = torch.arange(n)
    codes = fsq.indices_to_codes(idx)
    assert torch.equal(fsq.codes_to_indices(codes), idx)
    assert len({tuple(c) for c in codes.tolist()}) == n  # all distinct grid points
    assert codes.min() >= -1 and codes.max() <= 1


def test_fsq_quantize_lands_on_the_grid_and_covers_every_code():
    fsq = FSQ((8, 6, 5), 4)
    z = torch.randn(50000, 3, generator=torch.Generator().manual_seed(0))
    q = fsq.quantize(z)
    idx = fsq.codes_to_indices(q)
    torch.testing.assert_close(fsq.indices_to_codes(idx), q)
    assert idx.unique().numel() == 240


def test_fsq_grid_values_by_hand_for_five_levels():
    fsq = FSQ((5,), 4)
    q = fsq.quantize(torch.tensor([[-100.0], [0.0], [100.0]]))
    assert q.flatten().tolist() == [-1.0, 0.0, 1.0]
    assert fsq.codes_to_indices(q).tolist() == [0, 2, 4]


@settings(max_examples=20, deadline=None)
@given(st.lists(st.floats(-5, 5), min_size=3, max_size=3))
def test_fsq_straight_through_gradient_is_that_of_the_bound(values):
    fsq = FSQ((8, 6, 5), 4)
    z = torch.tensor([values], requires_grad=True)
    fsq.quantize(z).sum().backward()
    zz = z.detach().clone().requires_grad_(True)
    (fsq.bound(zz) / fsq.half_width).sum().backward()
    torch.testing.assert_close(z.grad, zz.grad)


def test_vq_picks_the_nearest_code_and_passes_gradient():
    vq = VQ(3, 2)
    with torch.no_grad():
        vq.codebook.copy_(torch.tensor([[0.0, 0.0], [1.0, 1.0], [-2.0, 0.0]]))
    z = torch.tensor([[[0.9, 1.2], [-1.5, 0.1], [0.1, -0.1]]], requires_grad=True)
    zq, idx, loss = vq(z)
    assert idx.tolist() == [[1, 2, 0]]
    torch.testing.assert_close(zq.detach(), vq.codebook[idx].detach())
    expected = 2 * (z.detach() - vq.codebook[idx].detach()).pow(2).mean()
    torch.testing.assert_close(loss.detach(), expected)
    zq.sum().backward()
    torch.testing.assert_close(z.grad, torch.ones_like(z))


def test_vq_loss_counts_only_weighted_positions():
    vq = VQ(2, 1)
    with torch.no_grad():
        vq.codebook.copy_(torch.tensor([[0.0], [10.0]]))
    z = torch.tensor([[[1.0], [3.0]]])
    _, _, loss = vq(z, torch.tensor([[1.0, 0.0]]))
    assert float(loss.detach()) == pytest.approx(2 * 1.0)
