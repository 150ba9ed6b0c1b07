"""StyGazeTalk through the streaming protocol: seed window, causality, determinism, checkpoints, factory."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
import torch

from dyadbench.errors import ConfigError, InputError
from dyadbench.protocol.causality import check_causal
from dyadbench.protocol.config import ProtocolConfig
from dyadbench.protocol.interface import ModelOptions
from dyadbench.protocol.streaming import stream_agent
from dyadbench.registry import MODELS
from dyadbench.synth.gaze import make_gaze_session
from dyadbench.synth.gaze_writer import write_session
from dyadbench.training.checkpoint import save_checkpoint
from models.stygazetalk.checkpoints import (load_style_model, load_system, save_style_model, save_system,
                                            system_from_style)
from models.stygazetalk.config import get_generator_config, get_style_config
from models.stygazetalk.generation import generate_session
from models.stygazetalk.registry import build_stygazetalk
from models.stygazetalk.train_style import StyleModel

torch.set_num_threads(1)
AGENT = "subject"


@pytest.fixture(scope="module")
def clip():
    return make_gaze_session("test", 0, seed=0, duration_s=8.0)  # 200 frames = 8 turns


def _system(name: str = "tiny-se64"):
    torch.manual_seed(0)
    cfg = get_generator_config(name)
    style = StyleModel(get_style_config(f"tiny-se{cfg.d_s}")) if cfg.style else None
    if style is not None:
        style.motion_norm.mean.copy_(torch.linspace(-1, 1, 7))
        style.motion_norm.std.copy_(torch.full((7,), 3.0))
    system = system_from_style(cfg, style)
    for p in system.generator.parameters():  # make the random generator visibly input-dependent
        p.data.mul_(3.0)
    system.residual_pool.copy_(0.3 * torch.randn(system.residual_pool.shape))
    return system.eval()


@pytest.fixture(scope="module")
def weights(tmp_path_factory):
    path = tmp_path_factory.mktemp("sgt") / "tiny-se64.pt"
    save_system(path, _system(), {"seed": 0})
    return path


def _model(weights, **extra):
    return build_stygazetalk(ModelOptions(weights=weights, extra=extra))


def test_registered_factory_builds_a_gaze7_streaming_model_with_a_seed_window(weights):
    model = MODELS.load("stygazetalk")(ModelOptions(weights=weights))
    assert model.info.layout == "gaze7" and not model.info.oracle
    assert model.info.seed_frames == 50 and len(model.info.weights_digest) == 64
    assert model.info.config["generator"]["variant"] == "SE-64"


def test_seed_turns_are_the_ground_truth_and_later_turns_are_generated(weights, clip):
    out = stream_agent(_model(weights), clip, AGENT, ProtocolConfig(context=2)).motion
    gt = clip.participants[0].motion
    assert out.shape == (200, 7)
    assert np.array_equal(out[:50], gt[:50])
    assert not np.allclose(out[50:], gt[50:], atol=1e-3)
    assert np.isfinite(out).all()


def test_streaming_equals_offline_sliding_window_generation(weights, clip):
    out = stream_agent(_model(weights), clip, AGENT, ProtocolConfig(context=1)).motion
    system, _ = load_system(weights)
    p = clip.participants[0]
    assert np.allclose(out, generate_session(system, p.audio, p.motion[:50], 200), atol=1e-5)


@pytest.mark.parametrize("name", ["tiny-se64", "tiny-tfm-se64"])
def test_causal_through_the_protocol(tmp_path, clip, name):
    path = save_system(tmp_path / f"{name}.pt", _system(name), {})
    for turn in (1, 3):  # inside the seed window, and after it
        check_causal(lambda: _model(path), clip, AGENT, ProtocolConfig(context=3), turn=turn)


def test_two_runs_are_bit_identical(weights, clip):
    cfg = ProtocolConfig(context=7, seed=3)
    a = stream_agent(_model(weights), clip, AGENT, cfg).motion
    b = stream_agent(_model(weights), clip, AGENT, cfg).motion
    assert np.array_equal(a, b)


def test_sampled_decoding_is_seeded_per_stream_and_causal(weights, clip):
    cfg = ProtocolConfig(context=2, seed=5)
    a = stream_agent(_model(weights, decoding="sample"), clip, AGENT, cfg).motion
    b = stream_agent(_model(weights, decoding="sample"), clip, AGENT, cfg).motion
    c = stream_agent(_model(weights, decoding="sample"), clip, AGENT, ProtocolConfig(context=2, seed=6)).motion
    mean = stream_agent(_model(weights), clip, AGENT, cfg).motion
    assert np.array_equal(a, b) and not np.allclose(a[50:], c[50:]) and not np.allclose(a[50:], mean[50:])
    # default sample_dims="gaze": the first generated frame differs from the mean only in the eye angles
    assert np.allclose(a[50, :3], mean[50, :3], atol=1e-6) and not np.allclose(a[50, 3:], mean[50, 3:])
    every = stream_agent(_model(weights, decoding="sample", sample_dims="all"), clip, AGENT, cfg).motion
    assert not np.allclose(every[50, :3], mean[50, :3])
    check_causal(lambda: _model(weights, decoding="sample"), clip, AGENT, cfg, turn=4)


def test_style_transfer_changes_the_motion_and_accepts_a_session_file(weights, clip, tmp_path):
    other = make_gaze_session("test", 3, seed=0, duration_s=6.0)
    cfg = ProtocolConfig(context=2)
    own = stream_agent(_model(weights), clip, AGENT, cfg).motion
    moved = stream_agent(_model(weights, style_from=other.participants[0].motion), clip, AGENT, cfg).motion
    assert np.array_equal(own[:50], moved[:50]) and not np.allclose(own[50:], moved[50:])
    npz = write_session(tmp_path / "test", other)
    from_file = stream_agent(_model(weights, style_from=str(npz)), clip, AGENT, cfg).motion
    assert np.array_equal(from_file, moved)
    with pytest.raises(InputError, match="not found"):
        _model(weights, style_from=str(tmp_path / "missing.npz"))


def test_mpgw_sim_corrupts_only_the_seed_gaze(weights, clip):
    cfg = ProtocolConfig(context=2)
    out = stream_agent(_model(weights, seed_window="mpgw-sim"), clip, AGENT, cfg).motion
    gt = clip.participants[0].motion
    assert np.array_equal(out[:50, :3], gt[:50, :3])
    assert np.array_equal(out[:50, 3:5], out[:50, 5:7]) and not np.allclose(out[:50, 3:], gt[:50, 3:])


def test_turn_length_must_divide_the_seed_window(weights, clip):
    with pytest.raises(ConfigError, match="divide"):
        stream_agent(_model(weights), clip, AGENT, ProtocolConfig(context=2, turn_seconds=0.6))


def test_checkpoint_round_trip(tmp_path, clip):
    system = _system()
    path = save_system(tmp_path / "g.pt", system, {"seed": 0})
    loaded, meta = load_system(path)
    assert loaded.cfg == system.cfg and loaded.se_cfg == system.se_cfg and meta["seed"] == 0
    for k, v in system.state_dict().items():
        assert torch.equal(v, loaded.state_dict()[k]), k
    p = clip.participants[0]
    wave = p.audio[25 * 640:75 * 640]
    assert np.array_equal(system.next_block(wave, p.motion[:50]), loaded.next_block(wave, p.motion[:50]))
    style = StyleModel(get_style_config("tiny-se32"))
    spath = save_style_model(tmp_path / "s.pt", style, {"seed": 1})
    style2, smeta = load_style_model(spath)
    assert style2.cfg == style.cfg and smeta["model"] == "stygazetalk-style"
    assert all(torch.equal(v, style2.state_dict()[k]) for k, v in style.state_dict().items())


def test_missing_or_foreign_checkpoints_get_clear_errors(tmp_path):
    with pytest.raises(InputError, match="dyadbench train stygazetalk"):
        build_stygazetalk(ModelOptions(weights=tmp_path / "none.pt"))
    foreign = save_checkpoint(tmp_path / "f.pt", model_state={}, config={}, meta={"model": "timar"})
    with pytest.raises(InputError, match="expected 'stygazetalk'"):
        load_system(foreign)
    style_ckpt = save_style_model(tmp_path / "s.pt", StyleModel(get_style_config("tiny-se32")), {})
    with pytest.raises(InputError, match="expected 'stygazetalk'"):
        load_system(style_ckpt)


def test_style_variants_need_a_matching_style_encoder():
    with pytest.raises(ValueError, match="d_s=64"):
        system_from_style(get_generator_config("tiny-se64"), StyleModel(get_style_config("tiny-se32")))
    base = system_from_style(replace(get_generator_config("tiny-base")), None)
    assert base.style_encoder is None
