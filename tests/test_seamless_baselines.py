"""Baselines on Seamless Interaction data: every one runs (or refuses clearly), fits use valid frames only."""

from __future__ import annotations

import numpy as np
import pytest

from baselines.fitting import frame_statistics
from baselines.retrieval import build_index
from baselines.trivial import build_mean_frame
from dyadbench.datasets.base import DyadicClip, InMemorySource, Participant
from dyadbench.datasets.seamless import SEAMLESS, open_split
from dyadbench.errors import ConfigError
from dyadbench.protocol.config import ProtocolConfig
from dyadbench.protocol.interface import ModelOptions
from dyadbench.protocol.runner import evaluate
from dyadbench.protocol.train_split import TrainSplit
from dyadbench.registry import MODELS
from dyadbench.synth.seamless_writer import write_seamless_split

#: every registered baseline and oracle reference row
BASELINES = sorted(e.name for e in MODELS.entries.values() if {"baseline", "oracle"} & set(e.tags))


@pytest.fixture(scope="module")
def root(tmp_path_factory):
    out = tmp_path_factory.mktemp("seamless-baselines")
    for split in ("test", "train"):
        write_seamless_split(out, split=split, clips=3, progress=False, duration_s=4.0)
    return out


def test_baseline_list_is_complete():
    assert {"zero", "mean-frame", "median-frame", "random", "mime", "lagged-mirror", "nn-retrieval",
            "oracle"} <= set(BASELINES)


@pytest.mark.parametrize("model", BASELINES)
def test_every_baseline_runs_on_seamless_or_refuses(root, model):
    source = open_split(root, "improvised/test")
    options = ModelOptions(train_split=TrainSplit("seamless", root))
    if "gaze" in MODELS.entries[model].tags:  # gaze-head models produce 7 angles: refused, naming both layouts
        with pytest.raises(ConfigError, match="produces gaze7 motion .*the split is seamless"):
            evaluate(model, source, ProtocolConfig(context=1), options=options, progress=False)
        return
    result = evaluate(model, source, ProtocolConfig(context=1), options=options, progress=False)
    assert result.suite == "seamless" and result.data.clips == 3 and result.data.items == 6
    for key in ("fd_expression", "mse_head", "FRCorr", "FRDist"):
        assert np.isfinite(result.metrics[key]), (model, key)
    if model == "oracle":
        assert result.metrics["fd_expression"] == pytest.approx(0.0, abs=1e-4)  # sqrtm of a singular product
        assert result.metrics["mse_expression"] == 0.0


def _participant(name: str, value: float, frames: int = 120, invalid: slice = slice(60, 120)) -> Participant:
    """Feature columns ``value`` on valid frames; an invalid block zero-filled with validity 0, as the corpus."""
    motion = np.full((frames, SEAMLESS.dim), value, np.float32)
    motion[:, -1] = 1.0
    motion[invalid] = 0.0
    return Participant(name, motion, np.zeros(frames * 16_000 // 30, np.float32))


def _source() -> InMemorySource:
    clips = [DyadicClip("a", (_participant("P1", 2.0), _participant("P2", 4.0)), fps=30.0, layout=SEAMLESS.name),
             DyadicClip("b", (_participant("P3", 6.0), _participant("P4", 8.0)), fps=30.0, layout=SEAMLESS.name)]
    return InMemorySource(clips, dataset="seamless-memory", split="train")


def test_fitted_statistics_use_valid_frames_only():
    stats = frame_statistics(_source())
    # by hand: valid frames hold 2, 4, 6, 8 (60 frames each) -> mean 5, median (4 + 6) / 2 = 5, 240 frames;
    # counting the 240 zero-filled frames as well would give mean 2.5 and median 1
    assert stats["frames"] == 240
    np.testing.assert_allclose(stats["mean"][:-1], 5.0)
    np.testing.assert_allclose(stats["median"][:-1], 5.0)
    assert stats["mean"][-1] == 1.0
    # variance of {2, 4, 6, 8} x 60 frames, ddof 1: sum((x - 5)^2) * 60 / 239 = 20 * 60 / 239
    np.testing.assert_allclose(stats["cov"][0, 0], 20 * 60 / 239)
    model = build_mean_frame(ModelOptions(train_split=_source, extra={"layout": SEAMLESS.name}))
    np.testing.assert_allclose(model.frame[:-1], 5.0)


def test_retrieval_index_never_holds_invalid_turns():
    # 4-s clip, 1-s turns of 30 frames: P1 invalid in turns 2-3, P2 in turn 1 -> only turn 0 is valid for both
    clip = DyadicClip("a", (_participant("P1", 2.0), _participant("P2", 4.0, invalid=slice(30, 60))), fps=30.0,
                      layout=SEAMLESS.name)
    index = build_index(InMemorySource([clip], dataset="seamless-memory", split="train"), turn_seconds=1.0)
    targets = index["targets"]  # one turn per direction: P1's turn 0 (value 2) and P2's turn 0 (value 4)
    assert targets.shape == (2, 30, SEAMLESS.dim)
    assert (targets[:, :, -1] == 1.0).all()
    assert sorted(np.unique(targets[:, :, :-1]).tolist()) == [2.0, 4.0]
