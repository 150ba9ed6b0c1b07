"""TIMAR per-dimension motion normalisation: units round-trip, training stores the statistics in the
checkpoint, and checkpoints from before the statistics existed load as identity."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
import torch
from protocol_clips import make_clip, make_source
from test_timar_model import MICRO, F, micro_model, random_inputs

from dyadbench.errors import ConfigError
from dyadbench.protocol.config import ProtocolConfig
from dyadbench.protocol.interface import ModelOptions
from dyadbench.protocol.streaming import stream_agent
from dyadbench.training.checkpoint import load_checkpoint, save_checkpoint
from models.timar.config import MOTION_STD_FLOOR, preset
from models.timar.data import WindowDataset
from models.timar.frontends import make_frontend
from models.timar.registry import build_timar, build_timar_stream
from models.timar.train import TrainSettings, train_timar_model

BUILD = {"timar": (build_timar, "faithful"), "timar-stream": (build_timar_stream, "stream")}


def with_stats(model: torch.nn.Module, seed: int = 4) -> tuple[torch.Tensor, torch.Tensor]:
    g = torch.Generator().manual_seed(seed)
    mean, std = torch.randn(56, generator=g), torch.rand(56, generator=g) * 2 + 0.05
    model.motion_mean.copy_(mean)
    model.motion_std.copy_(std)
    return mean, std


def test_presets_record_the_choice_and_unknown_values_are_refused():
    assert preset("tiny").motion_norm == "per_dim"
    assert preset("large").motion_norm == "none"  # the release feeds raw motion
    with pytest.raises(ConfigError, match="motion_norm"):
        preset("tiny", motion_norm="global")


def test_normalise_then_denormalise_is_the_identity():
    model = micro_model("faithful")
    with_stats(model)
    x = torch.randn(3, 7, 56) * 0.3
    torch.testing.assert_close(model.denormalize_motion(model.normalize_motion(x)), x)
    assert not torch.allclose(model.normalize_motion(x), x)


def test_samples_come_out_in_the_original_units():
    model = micro_model("faithful")
    cond = torch.randn(1, F, 16)
    plain = model.sample_frames(cond, torch.Generator().manual_seed(0))
    mean, std = with_stats(model)
    scaled = model.sample_frames(cond, torch.Generator().manual_seed(0))
    torch.testing.assert_close(scaled, plain * std + mean)


def test_loss_sees_motion_in_normalised_units():
    # a model with statistics (m, s) on raw motion has the loss of an identity model on (x - m) / s
    normed, identity = micro_model("faithful").train(), micro_model("faithful").train()
    mean, std = with_stats(normed)
    inputs = {k: v.reshape(2, 3 * F, -1) for k, v in random_inputs(2, 3).items()}
    agent = torch.randn(2, 3 * F, 56) * 0.2

    def loss(model, user_motion, agent_motion) -> torch.Tensor:
        torch.manual_seed(11)
        with torch.no_grad():
            return model(inputs["user_speech"], user_motion, inputs["agent_speech"], agent_motion)

    torch.testing.assert_close(loss(normed, inputs["user_motion"], agent),
                               loss(identity, (inputs["user_motion"] - mean) / std, (agent - mean) / std))


@pytest.fixture(scope="module")
def source():
    return make_source(2, seconds=2.0, split="train")


@pytest.mark.parametrize("norm", ["per_dim", "none"])
def test_training_stores_the_statistics_in_the_checkpoint(tmp_path, source, norm):
    cfg = preset("tiny", "faithful", motion_norm=norm, **MICRO)
    path = train_timar_model(cfg, source, tmp_path, TrainSettings(epochs=1, batch_size=4, stride_turns=2),
                             progress=False)
    state = load_checkpoint(path)
    assert state["config"]["motion_norm"] == norm
    mean, std = state["model"]["motion_mean"], state["model"]["motion_std"]
    if norm == "none":
        assert torch.equal(mean, torch.zeros(56)) and torch.equal(std, torch.ones(56))
    else:
        motion = np.concatenate([p.motion[:(c.num_frames // F) * F] for c in source for p in c.participants])
        np.testing.assert_allclose(mean.numpy(), motion.mean(0), atol=1e-5)
        np.testing.assert_allclose(std.numpy(), np.maximum(motion.std(0), MOTION_STD_FLOOR), rtol=1e-4)
    model = build_timar(ModelOptions(weights=path)).model  # loaded with the same statistics
    assert torch.equal(model.motion_mean, mean) and torch.equal(model.motion_std, std)


def test_motion_statistics_floor_a_constant_dimension(source):
    cfg = preset("tiny", "faithful", **MICRO)
    dataset = WindowDataset(source, make_frontend(cfg), cfg, stride_turns=2, progress=False)
    for feats in dataset.features:
        for f in feats.values():
            f.motion[:, 55] = 0.25
    mean, std = dataset.motion_statistics()
    assert mean[55] == pytest.approx(0.25) and std[55] == MOTION_STD_FLOOR and (std[:55] > MOTION_STD_FLOOR).all()


@pytest.mark.parametrize("name", BUILD)
def test_checkpoint_without_statistics_loads_as_identity(tmp_path, name):
    build, variant = BUILD[name]
    model = micro_model(variant)
    old_config = {k: v for k, v in replace(model.cfg, motion_norm="none").to_dict().items() if k != "motion_norm"}
    old_state = {k: v for k, v in model.state_dict().items() if k not in ("motion_mean", "motion_std")}
    old = save_checkpoint(tmp_path / "old.pt", model_state=old_state, config=old_config,
                          meta={"model": name, "data_digest": "test"})
    new = save_checkpoint(tmp_path / "new.pt", model_state=model.state_dict(),
                          config=replace(model.cfg, motion_norm="none").to_dict(),
                          meta={"model": name, "data_digest": "test"})
    loaded = build(ModelOptions(weights=old))
    assert loaded.model.cfg.motion_norm == "none"
    assert torch.equal(loaded.model.motion_mean, torch.zeros(56))
    assert torch.equal(loaded.model.motion_std, torch.ones(56))
    config = ProtocolConfig(turn_seconds=0.2, context=2)
    clip = make_clip("c0", 1.6, seed=5)
    np.testing.assert_array_equal(stream_agent(loaded, clip, "speaker1", config).motion,
                                  stream_agent(build(ModelOptions(weights=new)), clip, "speaker1", config).motion)
