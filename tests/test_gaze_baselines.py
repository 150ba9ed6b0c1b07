"""The two gaze–head reference rows, run through the streaming protocol on single-participant sessions."""

import numpy as np
import pytest
from scipy.ndimage import gaussian_filter1d

from dyadbench.datasets.base import InMemorySource
from dyadbench.errors import ConfigError
from dyadbench.protocol.causality import check_causal
from dyadbench.protocol.config import ProtocolConfig
from dyadbench.protocol.interface import ModelOptions
from dyadbench.protocol.offline import run_offline
from dyadbench.protocol.streaming import stream_agent
from dyadbench.registry import MODELS
from dyadbench.scoring.gaze import score_arrays
from dyadbench.scoring.report import ScoreItem
from dyadbench.synth.gaze import make_gaze_sessions

CONFIG = ProtocolConfig(context=2)


@pytest.fixture(scope="module")
def test_clips():
    return make_gaze_sessions("test", 8, seed=0, duration_s=30)


def build(name, **extra):
    train = make_gaze_sessions("train", 4, seed=0, duration_s=10)
    return MODELS.load(name)(ModelOptions(extra=extra, train_split=lambda: InMemorySource(train, "mem", "train")))


def run(model, clips):
    out = []
    for clip in clips:
        streamed = stream_agent(model, clip, "subject", CONFIG)
        p = clip.participants[0]
        out.append(ScoreItem(streamed.stem, streamed.motion, p.motion, audio=p.audio))
    return out


def test_static_is_straight_ahead_and_still(test_clips):
    model = build("gaze-static")
    assert model.info.layout == "gaze7" and model.info.config == {"rest": "zero"} and not model.info.oracle
    out = stream_agent(model, test_clips[0], "subject", CONFIG)
    assert out.stem == f"{test_clips[0].clip_id}_subject" and out.motion.shape == (750, 7)
    assert not out.motion.any()
    offline = run_offline(model, test_clips[0], "subject", CONFIG)
    np.testing.assert_array_equal(offline.motion[:750], out.motion)


def test_static_train_mean_holds_the_mean_head(tmp_path, monkeypatch, test_clips):
    monkeypatch.setenv("DYADBENCH_CACHE", str(tmp_path))
    train = make_gaze_sessions("train", 4, seed=0, duration_s=10)
    model = build("gaze-static", rest="train-mean")
    mean_head = np.concatenate([c.participants[0].motion for c in train]).astype(float).mean(axis=0)[:3]
    frame = stream_agent(model, test_clips[0], "subject", CONFIG).motion[0]
    np.testing.assert_allclose(frame[:3], mean_head, atol=1e-5)
    assert not frame[3:].any() and model.info.weights_digest


def test_headcopy_reads_the_head_and_centres_the_eyes(test_clips):
    model = build("gaze-headcopy")
    assert model.info.oracle
    gt = test_clips[0].participants[0].motion
    out = stream_agent(model, test_clips[0], "subject", CONFIG).motion
    np.testing.assert_array_equal(out[:, :3], gt[:750, :3])
    assert not out[:, 3:].any()
    in_space = stream_agent(build("gaze-headcopy", eye_convention="gaze-in-space"), test_clips[0], "subject",
                            CONFIG).motion
    np.testing.assert_array_equal(in_space[:, 3:5], gt[:750, 0:2])
    np.testing.assert_array_equal(in_space[:, 5:7], gt[:750, 0:2])


def test_options_are_checked():
    with pytest.raises(ConfigError, match="rest"):
        build("gaze-static", rest="middle")
    with pytest.raises(ConfigError, match="eye_convention"):
        build("gaze-headcopy", eye_convention="cyclops")


@pytest.mark.parametrize("name", ["gaze-static", "gaze-headcopy"])
def test_causal(name, test_clips):
    check_causal(lambda: build(name), test_clips[1], "subject", CONFIG, turn=5)


def test_baselines_score_worse_than_ground_truth_and_a_plausible_reference(test_clips):
    gt = score_arrays([ScoreItem(f"{c.clip_id}_subject", c.participants[0].motion, c.participants[0].motion,
                                 audio=c.participants[0].audio) for c in test_clips])
    blurred = score_arrays([ScoreItem(f"{c.clip_id}_subject",
                                      gaussian_filter1d(c.participants[0].motion, 1.0, axis=0),
                                      c.participants[0].motion) for c in test_clips])
    static = score_arrays(run(build("gaze-static"), test_clips))
    headcopy = score_arrays(run(build("gaze-headcopy"), test_clips))
    assert gt.metrics["sim_gt_seq"] == 1.0
    for row in (static, headcopy):
        assert row.metrics["sim_gt_seq"] < blurred.metrics["sim_gt_seq"] - 0.1
        assert row.metrics["fix_ratio"] == 1.0  # neither moves its eyes
    assert static.metrics["sim_gt_seq"] < headcopy.metrics["sim_gt_seq"]  # a real head gives the right CompScore
    assert headcopy.metrics["mae_head"] == 0.0
