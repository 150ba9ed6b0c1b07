"""The keyframe-placement oracle: exact on hand-made cases, and a true minimum over placements."""

from itertools import combinations

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from models.sfms.placement import interpolation_mse, optimal_placement_mse


def test_piecewise_linear_signal_is_rebuilt_exactly_from_its_corners():
    t = np.arange(20, dtype=float)
    w = np.stack([np.interp(t, [0, 7, 12, 19], [0.0, 3.0, -1.0, 2.0]), np.interp(t, [0, 7, 12, 19], [1, 1, 5, 0])], 1)
    assert interpolation_mse(w, [0, 7, 12, 19]) == pytest.approx(0.0, abs=1e-24)
    assert optimal_placement_mse(w, 4) == pytest.approx(0.0, abs=1e-24)
    assert interpolation_mse(w, [0, 6, 12, 18]) > 0.01


def test_held_ends_by_hand():
    w = np.array([[0.0], [1.0], [2.0], [3.0]])
    # one keyframe at frame 1: errors 1, 0, 1, 4 -> 6 / 4
    assert interpolation_mse(w, [1]) == pytest.approx(1.5)
    # best single frame: frame 1 or 2 (sum of squares 6); the oracle finds it
    assert optimal_placement_mse(w, 1) == pytest.approx(1.5)


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 2**31 - 1), st.integers(4, 9), st.integers(1, 4))
def test_oracle_equals_brute_force_minimum(seed, length, k):
    w = np.random.default_rng(seed).normal(size=(length, 3))
    brute = min(interpolation_mse(w, list(c)) for c in combinations(range(length), k))
    assert optimal_placement_mse(w, k) == pytest.approx(brute, rel=1e-12, abs=1e-15)


def test_all_frames_as_keyframes_is_exact_and_bad_input_is_refused():
    w = np.random.default_rng(0).normal(size=(6, 2))
    assert optimal_placement_mse(w, 6) == pytest.approx(0.0, abs=1e-24)
    with pytest.raises(ValueError, match="1 <= k <= T"):
        optimal_placement_mse(w, 7)
    with pytest.raises(ValueError, match="positions must lie"):
        interpolation_mse(w, [0, 6])
