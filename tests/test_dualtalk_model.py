"""DualTalk in dyadbench: the shipped checkpoint, both protocols, causality, normalisation, loss, training."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import torch

from dyadbench.datasets.base import InMemorySource
from dyadbench.errors import ConfigError
from dyadbench.protocol.causality import check_causal
from dyadbench.protocol.config import ProtocolConfig
from dyadbench.protocol.interface import ModelOptions, OfflineModel, StreamContext, StreamingModel, TurnInput
from dyadbench.protocol.offline import run_offline
from dyadbench.protocol.streaming import stream_agent
from dyadbench.training.checkpoint import load_checkpoint, save_checkpoint
from models.dualtalk.config import preset
from models.dualtalk.model import DualTalkModel
from models.dualtalk.registry import build_dualtalk, build_dualtalk_offline, shipped
from models.dualtalk.speech import normalise_waveform
from models.dualtalk.train import TrainSettings, dualtalk_loss, train_dualtalk_model
from protocol_clips import make_clip

MICRO = preset("tiny", feature_dim=8, ff_dim=16)


@pytest.fixture(scope="module")
def weights(tmp_path_factory) -> Path:
    torch.manual_seed(0)
    model = DualTalkModel(MICRO)
    with torch.no_grad():
        model.joint_encoder.speech_mean.fill_(-5.0)
        model.joint_encoder.speech_std.fill_(3.0)
    return save_checkpoint(tmp_path_factory.mktemp("dualtalk") / "micro.pt", model_state=model.state_dict(),
                           config=MICRO.to_dict(), meta={"model": "dualtalk", "data_digest": "test"})


def test_shipped_checkpoint_is_committed_and_loads():
    assert shipped().is_file(), f"{shipped()} is missing: train it with the command in models/dualtalk/cli.py"
    assert shipped().stat().st_size < 8 * 2**20
    model = build_dualtalk(ModelOptions())
    assert model.info.name == "dualtalk" and model.info.config["speech_frontend"] == "logmel"
    assert "dyadbench train dualtalk" in model.info.config["train_command"]


def test_streaming_is_causal(weights):
    clip = make_clip("c1", 4.0, seed=2)
    for turn in (0, 2):
        check_causal(lambda: build_dualtalk(ModelOptions(weights=weights)), clip, "speaker2",
                     ProtocolConfig(context=2), turn)


def test_offline_model_reads_the_future_and_is_recorded_offline(weights):
    model = build_dualtalk_offline(ModelOptions(weights=weights))
    assert isinstance(model, OfflineModel) and not isinstance(model, StreamingModel)
    clip = make_clip("c2", 3.0, seed=3)
    out = run_offline(model, clip, "speaker1", ProtocolConfig())
    assert out.protocol == "offline" and out.motion.shape == (75, 56)
    later = replace(clip, participants=tuple(replace(p, audio=np.where(np.arange(len(p.audio)) >= 32_000, 0.5, p.audio)
                                                     .astype(np.float32)) for p in clip.participants))
    changed = run_offline(model, later, "speaker1", ProtocolConfig()).motion  # only the last second differs
    assert np.abs(changed[:25] - out.motion[:25]).max() > 1e-4  # whole-sequence model: turn 0 reads turn 2


def test_stream_turn_equals_the_offline_model_on_the_window(weights):
    """Turn t under context n = the last turn of the whole-clip model run on turns t-min(t,n)..t alone."""
    clip = make_clip("c3", 5.0, seed=4)
    stream = stream_agent(build_dualtalk(ModelOptions(weights=weights)), clip, "speaker1",
                          ProtocolConfig(context=2)).motion
    offline = build_dualtalk_offline(ModelOptions(weights=weights))
    agent, user = clip.participant("speaker1"), clip.participant("speaker2")
    for t in range(5):
        h = min(t, 2)
        f0, f1, s0, s1 = (t - h) * 25, (t + 1) * 25, (t - h) * 16_000, (t + 1) * 16_000
        window = offline.predict_clip(None, user.motion[f0:f1], user.audio[s0:s1], agent.audio[s0:s1])
        np.testing.assert_allclose(stream[t * 25:(t + 1) * 25], window[-25:], atol=1e-6)


def _turn(clip, t: int, h: int) -> TurnInput:
    agent, user = clip.participant("speaker1"), clip.participant("speaker2")
    f0, f1, s0, s1 = (t - h) * 25, (t + 1) * 25, (t - h) * 16_000, (t + 1) * 16_000
    return TurnInput(t, h, 25, 16_000, user.motion[f0:f1], user.audio[s0:s1], agent.audio[s0:s1])


def test_clip_speech_norm_uses_the_given_whole_clip_statistics(weights):
    clip = make_clip("c4", 3.0, seed=5)
    loud = replace(clip, participants=tuple(replace(p, audio=p.audio * np.where(np.arange(len(p.audio)) < 16_000,
                                                                                 8.0, 1.0).astype(np.float32))
                                            for p in clip.participants))
    def stats(c, name):  # noqa: E306
        a = np.asarray(c.participant(name).audio, np.float64)
        return float(a.mean()), float(a.var())
    outputs = {}
    for label, c in (("quiet", clip), ("loud", loud)):
        for norm in ("window", "clip"):
            model = build_dualtalk(ModelOptions(weights=weights))
            model.start_stream(StreamContext("c4", "speaker1", "speaker2", 25.0, 16_000, 25, 16_000, 0, 3, 0,
                                             speech_norm=norm, agent_audio_stats=stats(c, "speaker1"),
                                             user_audio_stats=stats(c, "speaker2")))
            outputs[label, norm] = model.predict_turn(_turn(c, 2, 0))  # turn 2 alone: the loud turn 0 is outside
    np.testing.assert_array_equal(outputs["quiet", "window"], outputs["loud", "window"])
    assert np.abs(outputs["quiet", "clip"] - outputs["loud", "clip"]).max() > 1e-4
    with pytest.raises(ConfigError, match="statistics"):
        build_dualtalk(ModelOptions(weights=weights)).start_stream(
            StreamContext("c4", "speaker1", "speaker2", 25.0, 16_000, 25, 16_000, 0, 3, 0, speech_norm="clip"))


def test_waveform_normalisation_formula():
    x = np.array([1.0, 2.0, 3.0, 6.0], np.float32)  # mean 3, variance 3.5
    np.testing.assert_allclose(normalise_waveform(x), (x - 3.0) / np.sqrt(3.5 + 1e-7), rtol=1e-6)
    np.testing.assert_allclose(normalise_waveform(x, (1.0, 4.0)), (x - 1.0) / np.sqrt(4.0 + 1e-7), rtol=1e-6)


def test_loss_is_the_released_sum_of_four_mses():
    target = torch.zeros(1, 2, 56)
    pred = torch.zeros(1, 2, 56)
    pred[0, 1, 0] = 1.0  # exp: 1 / (2 * 50); velocity: 1 / (1 * 56)
    pred[0, :, 50] = 2.0  # jaw: 2 frames x 4 / (2 * 3); no velocity
    loss, parts = dualtalk_loss(pred, target)
    assert parts["exp"] == pytest.approx(1 / 100) and parts["jaw"] == pytest.approx(8 / 6)
    assert parts["neck"] == 0.0 and parts["velocity"] == pytest.approx(1 / 56)
    assert float(loss) == pytest.approx(1 / 100 + 8 / 6 + 1 / 56)


def test_training_writes_a_loadable_checkpoint_with_its_command(tmp_path):
    source = InMemorySource([make_clip(f"t{i}", 3.0, seed=10 + i) for i in range(2)], dataset="handmade",
                            split="train")
    settings = TrainSettings(steps=3, batch_size=2, max_seconds=2, save_every=2, command="dyadbench train dualtalk")
    path = train_dualtalk_model(MICRO, source, tmp_path / "run", settings, export=tmp_path / "w.pt", progress=False)
    payload = load_checkpoint(path, expect_model="dualtalk")
    assert [h["step"] for h in payload["meta"]["history"]] == [2, 3]
    assert payload["meta"]["command"] == "dyadbench train dualtalk"
    assert float(payload["model"]["joint_encoder.speech_std"].min()) > 0
    model = build_dualtalk(ModelOptions(weights=tmp_path / "w.pt"))
    assert model.info.config["train_steps"] == 3


def test_training_refuses_the_released_wav2vec_size(tmp_path):
    source = InMemorySource([make_clip("t", 2.0)], dataset="handmade", split="train")
    with pytest.raises(ConfigError, match="log-mel"):
        train_dualtalk_model(preset("released"), source, tmp_path, TrainSettings(steps=1), progress=False)
