"""Trivial, partner-copy, retrieval and oracle baselines: exact outputs, fitting, caching, seeds,
and the structure of the embedded corpus as the baselines see it."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from baselines import fitting, retrieval
from baselines.oracle import build_oracle
from baselines.partner import build_lagged_mirror, build_mime
from baselines.retrieval import build_nn_retrieval
from baselines.trivial import build_mean_frame, build_median_frame, build_random, build_zero
from dyadbench.datasets.base import InMemorySource
from dyadbench.errors import ConfigError, InputError
from dyadbench.paths import cache_dir
from dyadbench.provenance import source_key
from dyadbench.protocol.config import ProtocolConfig
from dyadbench.protocol.interface import ModelOptions
from dyadbench.protocol.streaming import stream_agent
from tests.protocol_clips import isolated_cache, make_clip, make_source  # noqa: F401
from tests.protocol_expectations import corpus_structure_failures


@pytest.fixture
def train():
    return make_source(3, split="train", seed=2, seconds=4.0)


def _opts(train, **extra):
    return ModelOptions(train_split=lambda: train, extra=extra)


def _all_frames(source):
    return np.concatenate([p.motion for c in source for p in c.participants]).astype(np.float64)


def test_zero_mean_median_frames_are_exact(train):
    frames = _all_frames(train)
    clip = make_clip("q", 3.0, seed=9)
    for build, expected in ((build_zero, np.zeros(56)), (build_mean_frame, frames.mean(axis=0)),
                            (build_median_frame, np.median(frames, axis=0))):
        out = stream_agent(build(_opts(train)), clip, "speaker1", ProtocolConfig()).motion
        np.testing.assert_allclose(out, np.tile(expected, (75, 1)), rtol=1e-6, atol=1e-6)


def test_frame_statistics_match_numpy(train):
    stats = fitting.frame_statistics(train)
    frames = _all_frames(train)
    np.testing.assert_allclose(stats["mean"], frames.mean(axis=0), rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(stats["cov"], np.cov(frames, rowvar=False), rtol=1e-9, atol=1e-12)
    assert int(stats["frames"]) == frames.shape[0] and int(stats["median_stride"]) == 1


def test_median_is_strided_on_large_splits(train, monkeypatch):
    monkeypatch.setattr(fitting, "MEDIAN_MAX_FRAMES", 100)
    stats = fitting.frame_statistics(train)
    assert int(stats["median_stride"]) == 6  # ceil(3 clips * 2 people * 100 frames / 100)


def test_random_frames_are_seeded_per_stream_and_match_train_statistics(train):
    model = build_random(_opts(train))
    clip = make_clip("r", 40.0, seed=4)
    a = stream_agent(model, clip, "speaker1", ProtocolConfig(seed=1)).motion
    b = stream_agent(build_random(_opts(train)), clip, "speaker1", ProtocolConfig(seed=1)).motion
    c = stream_agent(model, clip, "speaker1", ProtocolConfig(seed=2)).motion
    d = stream_agent(model, clip, "speaker2", ProtocolConfig(seed=1)).motion
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, c) and not np.array_equal(a, d)
    frames = _all_frames(train)
    draws = np.concatenate([a, c, d]).astype(np.float64)
    sd = frames.std(axis=0)
    assert np.all(np.abs(draws.mean(axis=0) - frames.mean(axis=0)) < 0.15 * sd + 1e-6)
    np.testing.assert_allclose(draws.std(axis=0), sd, rtol=0.15)


def test_mime_copies_the_partner_and_lagged_mirror_delays_it(train):
    clip = make_clip("m", 4.0, seed=6)
    partner = clip.participant("speaker2").motion
    mime = stream_agent(build_mime(_opts(train)), clip, "speaker1", ProtocolConfig(context=0)).motion
    np.testing.assert_array_equal(mime, partner[:100])
    lag = stream_agent(build_lagged_mirror(_opts(train)), clip, "speaker1", ProtocolConfig(context=0)).motion
    np.testing.assert_array_equal(lag[12:], partner[:88])  # 0.48 s = 12 frames at 25 fps
    np.testing.assert_array_equal(lag[:12], np.repeat(partner[:1], 12, axis=0))
    long_lag = ModelOptions(extra={"lag_seconds": 1.6})  # longer than a turn: the delay line spans turns
    out = stream_agent(build_lagged_mirror(long_lag), clip, "speaker1", ProtocolConfig()).motion
    np.testing.assert_array_equal(out[40:], partner[:60])


def test_partner_baselines_refuse_sessions_without_partner():
    clip = make_clip("solo", 2.0, participants=1)
    for build in (build_mime, build_lagged_mirror):
        with pytest.raises(InputError, match="no partner"):
            stream_agent(build(ModelOptions()), clip, "speaker1", ProtocolConfig())


def test_retrieval_returns_the_agent_turn_of_an_indexed_partner_turn(train):
    model = build_nn_retrieval(_opts(train))
    clip = train.load(train.clip_ids()[1])
    out = stream_agent(model, clip, "speaker2", ProtocolConfig(context=3)).motion
    np.testing.assert_array_equal(out, clip.participant("speaker2").motion[:100])
    assert model.info.config["index_turns"] == 3 * 2 * 4


def test_retrieval_outputs_are_whole_train_turns(train):
    model = build_nn_retrieval(_opts(train))
    turns = model.index["targets"]
    out = stream_agent(model, make_clip("new", 3.0, seed=77), "speaker1", ProtocolConfig()).motion
    for t in range(3):
        assert any(np.array_equal(out[t * 25:(t + 1) * 25], turn) for turn in turns)


def test_retrieval_features_describe_partner_motion_and_speech():
    r = np.random.default_rng(0)
    motion = r.standard_normal((2, 25, 56))
    audio = r.standard_normal((2, 16000)).astype(np.float32)
    feats = retrieval.partner_features(motion, retrieval.turn_speech(audio, None, 16000, 25.0))
    assert feats.shape == (2, 2 * 56 + 2 * retrieval.N_MELS)
    np.testing.assert_allclose(feats[:, :56], motion.mean(axis=1))
    np.testing.assert_allclose(feats[:, 56:112], motion.std(axis=1))
    shipped = r.standard_normal((2, 100, 128))  # dataset speech features: 4 rows × 128 bins per frame
    feats = retrieval.partner_features(motion, retrieval.turn_speech(audio, shipped, 16000, 25.0))
    np.testing.assert_allclose(feats[:, 112:], np.concatenate([shipped.mean(axis=1), shipped.std(axis=1)], axis=1))


def test_retrieval_index_is_built_for_the_protocol_turn_length(train):
    model = build_nn_retrieval(_opts(train))
    with pytest.raises(ConfigError, match="25-frame turns"):
        stream_agent(model, make_clip("x", 3.0), "speaker1", ProtocolConfig(turn_seconds=0.4))
    short = build_nn_retrieval(_opts(train, turn_seconds=0.4))
    out = stream_agent(short, make_clip("x", 3.0), "speaker1", ProtocolConfig(turn_seconds=0.4))
    assert out.motion.shape == (70, 56)


def test_fits_are_cached_by_the_split_digest(train, monkeypatch, tmp_path):
    monkeypatch.setenv("DYADBENCH_CACHE", str(tmp_path))
    calls = []
    original = fitting.frame_statistics
    monkeypatch.setattr("baselines.trivial.frame_statistics", lambda s: calls.append(1) or original(s))
    first = build_mean_frame(_opts(train))
    second = build_median_frame(_opts(train))
    assert len(calls) == 1
    assert first.info.weights_digest == second.info.weights_digest
    assert list((cache_dir() / "baselines").glob(f"frame-stats-v{fitting.STATS_VERSION}-*.npz"))
    other = make_source(2, split="train", seed=3, seconds=4.0)
    build_mean_frame(_opts(other))
    assert len(calls) == 2


def test_split_digest_follows_content(train):
    same = make_source(3, split="train", seed=2, seconds=4.0)
    assert source_key(train) == source_key(same)
    assert source_key(train) != source_key(make_source(3, split="train", seed=8))


def test_fitted_baselines_need_a_train_split():
    with pytest.raises(ConfigError, match="train split"):
        build_mean_frame(ModelOptions())
    with pytest.raises(InputError, match="no clips"):
        build_mean_frame(ModelOptions(train_split=lambda: InMemorySource([], split="train")))


def test_oracle_is_marked_and_copies_ground_truth():
    model = build_oracle(ModelOptions())
    assert model.info.oracle is True
    clip = make_clip("o", 3.2)
    out = stream_agent(model, clip, "speaker2", ProtocolConfig(tail="pad-last")).motion
    np.testing.assert_array_equal(out[:75], clip.participant("speaker2").motion[:75])


# --- the structure of the embedded corpus, seen through the baselines --------------------------------

def _suite_subset(pred, gt, partner, rng) -> dict[str, float]:
    """The suite's FD, P-FD, MSE, rPCC, variance and diversity of one item (no k-means SID: fast)."""
    from dyadbench.metrics import dualtalk as suite
    from dyadbench.motion import FLAME56

    pred, gt, partner = suite.truncate_to_shortest(*(np.asarray(x, np.float64) for x in (pred, gt, partner)))
    out = {}
    for c in ("exp", "jaw", "pose"):
        p, g, a = (FLAME56.component(x, c) for x in (pred, gt, partner))
        out.update({f"fd_{c}": suite.fd(p, g), f"pfd_{c}": suite.pfd(p, g, a), f"mse_{c}": suite.mse(p, g),
                    f"rpcc_{c}": suite.rpcc(p, g, a), f"var_pred_{c}": suite.variance(p),
                    f"var_gt_{c}": suite.variance(g), f"div_pred_{c}": suite.diversity(p, rng)})
    return out


@pytest.fixture(scope="module")
def corpus_scores(tmp_path_factory):
    """Every flame56 baseline streamed at n = 7 over a small generated test split (10 dialogues of 20 s),
    scored with the suite's own metric functions and averaged over clips as the suite does."""
    from dyadbench.protocol.runner import build_model, run_direction
    from dyadbench.synth.corpus import make_clips

    train = InMemorySource(make_clips("train", 10, seed=0, duration_s=20.0), "synthetic-small", "train")
    test = list(make_clips("test", 10, seed=0, duration_s=20.0))
    names = ["zero", "mean-frame", "median-frame", "random", "mime", "lagged-mirror", "nn-retrieval", "oracle"]
    options = ModelOptions(train_split=lambda: train, extra={"layout": "flame56", "turn_seconds": 1.0})
    scores = {}
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("DYADBENCH_CACHE", str(tmp_path_factory.mktemp("corpus-cache")))
        for name in names:
            model, rows = build_model(name, options), []
            for clip in test:
                for p in clip.participants:
                    pred = run_direction(model, clip, p.name, ProtocolConfig(context=7)).motion
                    rows.append(_suite_subset(pred, p.motion, clip.partner_of(p.name).motion,
                                              np.random.default_rng(0)))
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", RuntimeWarning)  # nanmean of rPCC, undefined for zero motion
                scores[name] = {k: float(np.nanmean([r[k] for r in rows])) for k in rows[0]}
    return scores


def test_corpus_structure_shows_on_a_small_generated_split(corpus_scores):
    assert corpus_structure_failures(corpus_scores) == []


def test_corpus_structure_check_names_what_fails(corpus_scores):
    broken = {k: dict(v) for k, v in corpus_scores.items()}
    broken["oracle"]["mse_jaw"] = 1e-3
    broken["lagged-mirror"]["pfd_exp"], broken["mime"]["pfd_exp"] = broken["mime"]["pfd_exp"], 0.0
    assert corpus_structure_failures(broken) == ["oracle mse_jaw = 0", "lagged-mirror pfd_exp < mime"]
