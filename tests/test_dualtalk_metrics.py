"""DualTalk/TIMAR metrics: hand-computable cases, properties, and independent cross-checks."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from dyadbench.errors import InputError
from dyadbench.metrics import dualtalk as m

SID_LOWER = -math.log2(1 + 1e-6)  # a single occupied cluster: -1 * log2(1 + 1e-6)


def _gauss(seed, t, d, scale=1.0, shift=0.0):
    return shift + scale * np.random.default_rng(seed).normal(size=(t, d))


# --- hand-computable cases -------------------------------------------------------------------------

def test_fd_equal_covariances_is_squared_mean_difference():
    x = _gauss(0, 200, 5)
    delta = np.array([1.0, -2.0, 0.5, 0.0, 3.0])
    assert m.fd(x + delta, x) == pytest.approx(float(delta @ delta), rel=1e-8)


def test_identical_inputs_give_zero():
    p = _gauss(1, 120, 4)
    a = _gauss(2, 120, 4)
    assert m.fd(p, p) == pytest.approx(0.0, abs=1e-9)
    assert m.pfd(p, p, a) == pytest.approx(0.0, abs=1e-9)
    assert m.mse(p, p) == 0.0
    assert m.rpcc(p, p, a) == 0.0
    assert m.sts(p, p) == 0.0


def test_fd_of_two_scaled_gaussians_by_hand():
    # 1-d: FD = (mu1-mu2)^2 + s1^2 + s2^2 - 2 s1 s2 = (mu1-mu2)^2 + (s1-s2)^2, exact for sample stats.
    x = _gauss(3, 300, 1)
    y = 3.0 * x + 2.0
    s1 = np.std(x, ddof=1)
    expected = (x.mean() - y.mean()) ** 2 + (s1 - 3.0 * s1) ** 2
    assert m.fd(x, y) == pytest.approx(expected, rel=1e-9)


def test_mse_by_hand():
    assert m.mse(np.array([[1.0, 2.0], [3.0, 4.0]]), np.zeros((2, 2))) == pytest.approx(30 / 4)


def test_sts_by_hand():
    p = np.array([[0.0], [1.0], [3.0]])
    g = np.zeros((3, 1))
    # velocities of p: 1, 2; of g: 0, 0 -> sqrt((1 + 4) / 0.1)
    assert m.sts(p, g) == pytest.approx(math.sqrt(50.0))
    # a constant offset does not change velocities
    assert m.sts(p + 5.0, p) == 0.0


def test_rpcc_by_hand():
    a = np.arange(8.0).reshape(4, 2)
    assert m.rpcc(-a, a, a) == pytest.approx(2.0)  # corr(g, a) = 1, corr(p, a) = -1
    assert m.rpcc(a * 3 + 1, a, a) == pytest.approx(0.0, abs=1e-12)


def test_rpcc_undefined_for_constant_prediction():
    a = _gauss(4, 50, 3)
    assert math.isnan(m.rpcc(np.zeros((50, 3)), a + 1, a))


def test_variance_by_hand():
    assert m.variance(np.array([[0.0, 1.0], [2.0, 1.0]])) == pytest.approx(0.5)  # (1 + 0) / 2


def _clustered(counts, centers):
    """Rows: counts[i] copies of centers[i]."""
    return np.concatenate([np.repeat(c[None], n, axis=0) for c, n in zip(centers, counts)])


CENTERS = np.arange(10.0)[:, None] * np.array([10.0, -7.0, 3.0])


def test_sid_on_constructed_clustering():
    p = _clustered([10] * 10, CENTERS)                   # 10 well separated clusters
    g_uniform = _clustered([5] * 10, CENTERS)            # every cluster equally used
    g_two = _clustered([30, 10, 0, 0, 0, 0, 0, 0, 0, 0], CENTERS)  # q = 3/4, 1/4
    assert m.sid(p, g_uniform, 10) == pytest.approx(-10 * 0.1 * math.log2(0.1 + 1e-6), rel=1e-12)
    expected_two = -(0.75 * math.log2(0.75 + 1e-6) + 0.25 * math.log2(0.25 + 1e-6))
    assert m.sid(p, g_two, 10) == pytest.approx(expected_two, rel=1e-12)
    assert m.sid(p, CENTERS[[4] * 20], 10) == pytest.approx(SID_LOWER, abs=1e-12)


def test_sid_orientations_are_argument_swaps():
    p, g = _gauss(5, 80, 3), _gauss(6, 80, 3, scale=2.0)
    assert m.sid_gtfit(p, g, 10) == m.sid(g, p, 10)
    assert m.sid_gtfit(p, g, 10) != m.sid(p, g, 10)


class _Draws:
    """A stand-in generator handing out fixed index draws and recording how it was asked."""

    def __init__(self, *draws):
        self.draws, self.calls = list(draws), []

    def choice(self, *args, **kwargs):
        self.calls.append((args, kwargs))
        return self.draws.pop(0)


def test_diversity_by_hand_on_fixed_draws():
    # frames x_t = (t, 0, 0); pairs (i, 99 - i) for i = 0..99: |2i - 99| averages 2 (1 + 3 + ... + 99) / 100 = 50
    x = np.zeros((120, 3))
    x[:, 0] = np.arange(120)
    rng = _Draws(np.arange(100), np.arange(99, -1, -1))
    assert m.diversity(x, rng) == 50.0
    assert rng.calls == [((120, 100), {"replace": False})] * 2
    # 3-4-5 triangles: frames alternate (0, 0) and (3, 4); pairs (2k, 2k + 1) are 5 apart, (2k, 2k) 0 apart
    y = np.zeros((100, 2))
    y[1::2] = (3.0, 4.0)
    first = np.arange(0, 100, 2).repeat(2)
    second = np.stack([first[::2], first[::2] + 1], axis=1).ravel()
    assert m.diversity(y, _Draws(first, second)) == 2.5


def test_diversity_is_seeded_and_zero_for_a_still_sequence():
    x = _gauss(7, 150, 3)
    assert m.diversity(x, np.random.default_rng(11)) == m.diversity(x, np.random.default_rng(11))
    assert m.diversity(x, np.random.default_rng(11)) != m.diversity(x, np.random.default_rng(12))
    assert m.diversity(np.ones((120, 3)), np.random.default_rng(0)) == 0.0


def test_diversity_needs_100_frames():
    assert math.isnan(m.diversity(_gauss(8, 99, 3), np.random.default_rng(0)))


# --- independent cross-checks of the Fréchet metrics ----------------------------------------------

def _direct_stats(x):
    t = x.shape[0]
    mu = np.array([sum(x[i, j] for i in range(t)) / t for j in range(x.shape[1])])
    centered = x - mu
    cov = sum(np.outer(centered[i], centered[i]) for i in range(t)) / (t - 1)
    return mu, cov


def _direct_frechet(x, y):
    """FD with tr sqrt(S1 S2) = sum of sqrt(eigenvalues of S1 S2) (real, >= 0 for SPD S1, S2)."""
    mu1, s1 = _direct_stats(x)
    mu2, s2 = _direct_stats(y)
    eig = np.linalg.eigvals(s1 @ s2).real
    return float(np.sum((mu1 - mu2) ** 2) + np.trace(s1) + np.trace(s2) - 2 * np.sum(np.sqrt(eig.clip(0))))


def test_fd_and_pfd_match_a_direct_computation():
    p, g, a = _gauss(9, 90, 4), _gauss(10, 90, 4, 1.5, 0.3), _gauss(11, 90, 4, 0.7)
    a = a + 0.5 * g  # partner correlated with the agent
    assert m.fd(p, g) == pytest.approx(_direct_frechet(p, g), rel=1e-9)
    paired = _direct_frechet(np.hstack([a, g]), np.hstack([a, p]))
    assert m.pfd(p, g, a) == pytest.approx(paired, rel=1e-9)


# --- properties ------------------------------------------------------------------------------------

seeds = st.integers(0, 2**31 - 1)
frames = st.integers(12, 60)
dims = st.integers(1, 4)
scales = st.floats(0.01, 10.0)


@settings(max_examples=40, deadline=None)
@given(seeds, frames, dims, scales, scales)
def test_fd_nonnegative_and_symmetric(seed, t, d, s1, s2):
    p, g = _gauss(seed, t, d, s1), _gauss(seed + 1, t, d, s2, 0.5)
    forward, backward = m.fd(p, g), m.fd(g, p)
    tol = 1e-9 * (s1 + s2) ** 2 * d
    assert forward >= -tol
    assert forward == pytest.approx(backward, rel=1e-7, abs=tol)
    assert m.pfd(p, g, _gauss(seed + 2, t, d)) >= -tol


@settings(max_examples=25, deadline=None)
@given(seeds, st.integers(10, 40), dims, st.sampled_from([2, 3, 10]))
def test_sid_bounds(seed, t, d, k):
    p, g = _gauss(seed, t, d), _gauss(seed + 1, t, d)
    for value in (m.sid(p, g, k), m.sid_gtfit(p, g, k)):
        assert SID_LOWER - 1e-12 <= value <= math.log2(k)


@settings(max_examples=60, deadline=None)
@given(seeds, frames, dims, scales)
def test_rpcc_mse_sts_variance_ranges(seed, t, d, s):
    p, g, a = _gauss(seed, t, d, s), _gauss(seed + 1, t, d), _gauss(seed + 2, t, d)
    assert 0.0 <= m.rpcc(p, g, a) <= 2.0
    assert m.rpcc(g, g, a) == 0.0
    assert m.mse(p, g) >= 0.0 and m.mse(p, g) == m.mse(g, p)
    assert m.sts(p, g) >= 0.0 and m.sts(p, g) == pytest.approx(m.sts(g, p))
    assert m.variance(p) >= 0.0


# --- the per-clip bundle ---------------------------------------------------------------------------

def _clip(seed, t=120):
    return _gauss(seed, t, 56, 0.3), _gauss(seed + 1, t, 56, 0.3), _gauss(seed + 2, t, 56, 0.3)


def test_clip_metrics_keys_and_zeros_on_identity():
    p, g, a = _clip(0)
    values = m.clip_metrics(g, g, a, seed=3)
    assert tuple(values) == m.KEYS
    for c in ("exp", "jaw", "pose"):
        assert values[f"mse_{c}"] == 0.0 and values[f"rpcc_{c}"] == 0.0 and values[f"sts_{c}"] == 0.0
        assert abs(values[f"fd_{c}"]) < 1e-9
        assert values[f"var_pred_{c}"] == values[f"var_gt_{c}"]
        assert values[f"div_pred_{c}"] == values[f"div_gt_{c}"]  # same frame pairs for both


def test_clip_diversity_follows_the_seed_rule():
    p, g, a = _clip(4, 130)
    values = m.clip_metrics(p, g, a, seed=77)
    for i, (c, cols) in enumerate((("exp", slice(0, 50)), ("jaw", slice(50, 53)), ("pose", slice(53, 56)))):
        assert values[f"div_pred_{c}"] == m.diversity(p[:, cols], np.random.default_rng([77, i]))
        assert values[f"div_gt_{c}"] == m.diversity(g[:, cols], np.random.default_rng([77, i]))


def test_clip_metrics_components_follow_the_layout():
    _, g, a = _clip(1)
    p = g.copy()
    p[:, 50:53] += 0.1  # jaw only
    values = m.clip_metrics(p, g, a, seed=0)
    assert values["mse_exp"] == 0.0 and values["mse_pose"] == 0.0
    assert values["mse_jaw"] == pytest.approx(0.01)


def test_clip_metrics_truncates_and_is_seeded():
    p, g, a = _clip(2, 150)
    full = m.clip_metrics(np.vstack([p, p[:10]]), g, a[:], seed=5)
    assert full == m.clip_metrics(p, g, a, seed=5)
    other = m.clip_metrics(p, g, a, seed=6)
    assert other["div_pred_exp"] != full["div_pred_exp"]
    assert {k: v for k, v in other.items() if not k.startswith("div")} == \
        {k: v for k, v in full.items() if not k.startswith("div")}


def test_clip_metrics_short_clips():
    p, g, a = _clip(3, 60)
    values = m.clip_metrics(p, g, a, seed=0)
    assert all(math.isnan(values[f"div_{w}_{c}"]) for w in ("pred", "gt") for c in ("exp", "jaw", "pose"))
    assert math.isfinite(values["sid_exp"])
    with pytest.raises(InputError, match="at least 40"):
        m.clip_metrics(p[:39], g, a, seed=0)
    with pytest.raises(InputError, match="56"):
        m.clip_metrics(p[:, :50], g, a, seed=0)


def test_publication_scaling_and_paper_order():
    assert m.PAPER_ORDER[:5] == ("fd", "pfd", "mse", "sid", "rpcc")
    assert (m.SCALE["fd_exp"], m.SCALE["fd_jaw"], m.SCALE["fd_pose"]) == (1.0, 1e3, 1e2)
    assert (m.SCALE["pfd_exp"], m.SCALE["pfd_jaw"], m.SCALE["pfd_pose"]) == (1.0, 1e3, 1e2)
    assert (m.SCALE["mse_exp"], m.SCALE["mse_jaw"], m.SCALE["mse_pose"]) == (10.0, 1e3, 1e2)
    assert (m.SCALE["rpcc_exp"], m.SCALE["rpcc_jaw"], m.SCALE["rpcc_pose"]) == (1e2, 10.0, 10.0)
    assert m.SCALE["sid_exp"] == 1.0 and m.SID_K == {"exp": 40, "jaw": 10, "pose": 10}
    assert m.HIGHER_IS_BETTER["sid_jaw"] is True and m.HIGHER_IS_BETTER["fd_exp"] is False
    assert m.HIGHER_IS_BETTER["rpcc_pose"] is False and m.HIGHER_IS_BETTER["var_pred_exp"] is None
    assert len(m.KEYS) == 33 and set(m.KEYS) == set(m.SCALE)
