"""Every registered model: causal (outputs up to turn t ignore later inputs), deterministic per seed.

A registered model whose module cannot be imported or whose committed weights cannot be built fails the
test with the reason: every registered model ships with the package.
"""

from __future__ import annotations

import numpy as np
import pytest

from dyadbench.errors import DyadbenchError
from dyadbench.protocol.causality import check_causal
from dyadbench.protocol.config import ProtocolConfig
from dyadbench.protocol.interface import ModelOptions, OfflineModel, StreamingModel
from dyadbench.protocol.offline import run_offline
from dyadbench.protocol.streaming import stream_agent
from dyadbench.registry import MODELS
from tests.protocol_clips import isolated_cache, make_clip, make_source  # noqa: F401


def _setting(name: str):
    """(clip, options factory) matching the model's layout: gaze models get single-participant gaze7."""
    gaze = "gaze" in MODELS.get(name).tags
    layout, people = ("gaze7", 1) if gaze else ("flame56", 2)
    train = make_source(3, split="train", seed=11, seconds=6.0, layout=layout, participants=people)
    clip = make_clip("causal", 5.0, seed=3, layout=layout, participants=people)

    def options(seed: int = 0) -> ModelOptions:
        return ModelOptions(seed=seed, train_split=lambda: train,
                            extra={"layout": layout, "turn_seconds": 1.0})
    return clip, options


def _factory(name: str, options: ModelOptions):
    """A zero-argument factory for ``name``; a test failure naming why the model cannot be built."""
    try:
        build = MODELS.load(name)
    except ImportError as exc:
        pytest.fail(f"registered model {name!r} cannot be imported: {exc}")
    try:
        build(options)
    except DyadbenchError as exc:
        pytest.fail(f"registered model {name!r} cannot be built from its committed files: {exc}")
    return lambda: build(options)


@pytest.mark.parametrize("name", MODELS.names())
@pytest.mark.parametrize("context", [0, 2])
def test_every_model_is_causal(name, context):
    clip, options = _setting(name)
    factory = _factory(name, options())
    if not isinstance(factory(), StreamingModel):
        pytest.skip(f"{name} is an offline (full-sequence) model: causality does not apply")
    for turn in (0, 2):
        check_causal(factory, clip, clip.participants[0].name, ProtocolConfig(context=context), turn)


@pytest.mark.parametrize("name", MODELS.names())
def test_every_model_is_deterministic_for_a_seed(name):
    clip, options = _setting(name)
    factory = _factory(name, options(seed=5))
    config = ProtocolConfig(context=2, seed=5)
    agent = clip.participants[0].name
    model = factory()
    if isinstance(model, StreamingModel):
        first = stream_agent(model, clip, agent, config).motion
        again = stream_agent(factory(), clip, agent, config).motion
        reused = stream_agent(model, clip, agent, config).motion  # start_stream must reset all state
    else:
        first = run_offline(model, clip, agent, config).motion
        again = run_offline(factory(), clip, agent, config).motion
        reused = run_offline(model, clip, agent, config).motion
    np.testing.assert_array_equal(first, again)
    np.testing.assert_array_equal(first, reused)


BOTH_INTERFACES = ["zero", "mean-frame", "median-frame", "random", "mime", "lagged-mirror", "nn-retrieval"]


@pytest.mark.parametrize("name", BOTH_INTERFACES)
@pytest.mark.parametrize("tail", ["truncate", "pad-last"])
def test_history_free_baselines_agree_streaming_and_offline(name, tail):
    clip, options = _setting(name)
    model = MODELS.load(name)(options())
    assert isinstance(model, StreamingModel) and isinstance(model, OfflineModel)
    config = ProtocolConfig(context=3, tail=tail)
    streamed = stream_agent(model, clip, "speaker2", config).motion
    offline = run_offline(MODELS.load(name)(options()), clip, "speaker2", config).motion
    assert offline.shape[0] == clip.num_frames
    whole = (clip.num_frames // 25) * 25
    np.testing.assert_array_equal(streamed[:whole], offline[:whole])
    for other in (0, 7):  # history-free: the context length changes nothing
        again = stream_agent(MODELS.load(name)(options()), clip, "speaker2", ProtocolConfig(context=other, tail=tail))
        np.testing.assert_array_equal(again.motion, streamed)
