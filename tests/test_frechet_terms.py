"""The Fréchet distance split into its mean and covariance terms."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from dyadbench.metrics.frechet import frechet_between, frechet_terms


def _gauss(seed, t, d, scale=1.0):
    return scale * np.random.default_rng(seed).normal(size=(t, d))


def test_offset_copy_has_only_a_mean_term():
    y = _gauss(0, 150, 3)
    offset = np.array([0.5, -1.0, 2.0])
    mean_term, cov_term = frechet_terms(y + offset, y)
    assert mean_term == pytest.approx(5.25, rel=1e-12)
    assert cov_term == pytest.approx(0.0, abs=1e-9)


def test_centred_inputs_have_only_a_covariance_term():
    x, y = _gauss(1, 200, 2), _gauss(2, 200, 2, 3.0)
    x, y = x - x.mean(0), y - y.mean(0)
    mean_term, cov_term = frechet_terms(x, y)
    assert mean_term == pytest.approx(0.0, abs=1e-24)
    assert cov_term == pytest.approx(frechet_between(x, y), rel=1e-12)


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 2**31 - 1), st.integers(5, 60), st.integers(1, 4), st.floats(0.01, 10.0))
def test_terms_sum_to_the_distance_and_are_nonnegative(seed, t, d, scale):
    x, y = _gauss(seed, t, d, scale), _gauss(seed + 1, t, d) + 0.3
    mean_term, cov_term = frechet_terms(x, y)
    whole = frechet_between(x, y)
    tol = 1e-9 * (1 + scale) ** 2 * d
    assert mean_term >= 0.0
    assert cov_term >= -tol
    assert mean_term + cov_term == pytest.approx(whole, rel=1e-9, abs=tol)
