"""The released TIMAR checkpoint converted by models.timar.official reproduces the released code's numbers.

Reference values are the fixture's ``outputs.npz`` (computed by the released code; see its README): the
per-turn conditioning vectors of the conditional branch (``z_cond``) and of the unconditional branch that
nulls the current turn's user frames (``z_uncond``), every turn of an 11-turn clip (the window of 8 turns
slides from turn 8 on), the diffusion MLP's outputs at given (x_t, t) and the 5-step respaced schedule.
"""

from __future__ import annotations

import numpy as np
import pytest
import torch

from dyadbench.errors import ConfigError
from dyadbench.protocol.config import ProtocolConfig
from dyadbench.protocol.interface import ModelOptions
from dyadbench.protocol.streaming import stream_agent
from models.timar import official
from models.timar.registry import build_timar
from tests.timar_official_fixture import CHECKPOINT, HEADS, WAV2VEC, arrays, fixture_clip

F = 25


@pytest.fixture(scope="module")
def fixture_arrays():
    return arrays()


@pytest.fixture(scope="module")
def converted():
    return official.load_official(CHECKPOINT, heads=HEADS)[0]


def conditions(model, outputs: dict, inputs: dict, turn: int, context: int = 7) -> torch.Tensor:
    """(2, F, D) conditions of ``turn`` from the fixture's speech features: conditional, then current-turn
    nulled, computed as the release's window (min(turn, context) history turns, all agent motion masked)."""
    dtype = model.pos_embed.dtype
    first = max(0, turn - context)
    window = slice(first, turn + 1)

    def frames(x: np.ndarray) -> torch.Tensor:
        return torch.tensor(np.asarray(x), dtype=dtype)[None].expand(2, -1, -1, -1)

    motion = inputs["motion_user"][:outputs["z_cond"].shape[0] * F].reshape(-1, F, 56)
    null = torch.zeros(2, turn + 1 - first, 2 * F, dtype=torch.bool)
    null[1, -1] = True
    with torch.no_grad():
        tokens = model.turn_tokens(frames(outputs["speech_feats_user"][window]), frames(motion[window]),
                                   frames(outputs["speech_feats_agent"][window]), user_null=null)
        return model.encode(tokens)[:, -1, model.agent_slice]


def max_conditioning_error(model, fixture_arrays) -> float:
    inputs, outputs = fixture_arrays
    worst = 0.0
    for turn in range(outputs["z_cond"].shape[0]):
        z = conditions(model, outputs, inputs, turn).double().numpy()
        worst = max(worst, np.abs(z[0] - outputs["z_cond"][turn]).max(), np.abs(z[1] - outputs["z_uncond"][turn]).max())
    return float(worst)


def test_conditioning_vectors_match_the_release_every_turn_in_float32(converted, fixture_arrays):
    assert fixture_arrays[1]["window_len_tokens"].tolist()[-3:] == [880] * 3  # the window slides after turn 7
    assert max_conditioning_error(converted, fixture_arrays) < 1e-5


def test_conditioning_vectors_match_the_release_in_float64(fixture_arrays):
    model = official.load_official(CHECKPOINT, heads=HEADS, dtype=torch.float64)[0]
    assert max_conditioning_error(model, fixture_arrays) < 1e-12


@pytest.mark.parametrize("dtype, tolerance", [(torch.float32, 1e-5), (torch.float64, 1e-6)])
def test_diffusion_network_outputs_match_the_release(fixture_arrays, dtype, tolerance):
    _, outputs = fixture_arrays
    model = official.load_official(CHECKPOINT, heads=HEADS, dtype=dtype)[0]
    x_t, t = outputs["diff_x_t"], outputs["diff_t_original"]
    with torch.no_grad():
        out = torch.stack([torch.stack([model.head(torch.tensor(x_t[k, j], dtype=dtype), torch.full((F,), int(t[j])),
                                                   torch.tensor(outputs["z_cond"][k], dtype=dtype))
                                        for j in range(len(t))]) for k in range(x_t.shape[0])])
    assert np.abs(out.double().numpy() - outputs["diff_net_out"]).max() < tolerance


def test_sampler_schedule_is_the_released_five_step_respacing(converted, fixture_arrays):
    _, outputs = fixture_arrays
    d = converted.sample_diffusion
    assert d.timestep_map.tolist() == outputs["sched_timestep_map"].tolist() == [0, 250, 500, 749, 999]
    np.testing.assert_allclose(d.betas, outputs["sched_betas"], rtol=1e-12, atol=0)
    np.testing.assert_allclose(d.alphas_cumprod, outputs["sched_alphas_cumprod"], rtol=1e-12, atol=0)
    tables = {"posterior_log_var": "sched_posterior_log_variance_clipped",
              "posterior_coef1": "sched_posterior_mean_coef1", "posterior_coef2": "sched_posterior_mean_coef2"}
    for ours, theirs in tables.items():  # float32 tables, as the release casts them when sampling
        np.testing.assert_allclose(d._tables[ours].numpy(), outputs[theirs].astype(np.float32), rtol=0, atol=0)


@pytest.mark.parametrize("cache", [True, False])
def test_streamed_conditions_match_the_release_with_clip_speech_normalisation(monkeypatch, fixture_arrays, cache):
    """The whole path: fixture clip -> protocol (speech_norm clip) -> wav2vec-tiny -> converted model."""
    inputs, outputs = fixture_arrays
    monkeypatch.setitem(official.FACTORY_HEADS, "timar_tiny_b", HEADS)
    stream = build_timar(ModelOptions(weights=CHECKPOINT, cfg_scale=3.0,
                                      extra={"wav2vec_weights": str(WAV2VEC), "cache": cache}))
    seen = []
    sample = stream.model.sample_frames
    monkeypatch.setattr(stream.model, "sample_frames", lambda z, *a, **k: seen.append(z) or sample(z, *a, **k))
    stream_agent(stream, fixture_clip(inputs), "speaker2", ProtocolConfig(context=7, speech_norm="clip"))
    z = torch.stack(seen).double().numpy()  # (turns, 2, F, D)
    assert np.abs(z[:, 0] - outputs["z_cond"]).max() < 1e-5
    assert np.abs(z[:, 1] - outputs["z_uncond"]).max() < 1e-5
    assert stream.info.config["format"] == "official" and stream.info.config["clamp_variance"] is False


def test_window_speech_normalisation_gives_the_same_conditions_cached_or_re_encoded(monkeypatch, fixture_arrays):
    """--speech-norm window normalises each turn's audio on its own, so the cached stream (each turn
    featurised once) and the re-encoding stream (the whole window featurised every turn) condition the
    diffusion head identically, also after the window slides (turn 8 on)."""
    inputs, _ = fixture_arrays
    monkeypatch.setitem(official.FACTORY_HEADS, "timar_tiny_b", HEADS)
    conditions = {}
    for cache in (True, False):
        stream = build_timar(ModelOptions(weights=CHECKPOINT, extra={"wav2vec_weights": str(WAV2VEC),
                                                                     "cache": cache}))
        seen = conditions[cache] = []
        sample = stream.model.sample_frames
        monkeypatch.setattr(stream.model, "sample_frames",
                            lambda z, *a, s=sample, k=seen, **kw: k.append(z) or s(z, *a, **kw))
        stream_agent(stream, fixture_clip(inputs), "speaker2", ProtocolConfig(context=7))
    cached, re_encoded = (torch.stack(conditions[c]).double().numpy() for c in (True, False))
    assert cached.shape[0] == 11 and np.abs(cached - re_encoded).max() < 1e-5


def test_the_model_key_instead_of_model_ema_fails_the_comparison(fixture_arrays):
    model = official.load_official(CHECKPOINT, heads=HEADS, weights="model")[0]
    assert max_conditioning_error(model, fixture_arrays) > 0.1


def test_a_perturbed_position_table_fails_the_comparison(converted, fixture_arrays):
    model = official.load_official(CHECKPOINT, heads=HEADS)[0]
    with torch.no_grad():
        model.head_pos_embed.add_(1e-3 * torch.randn_like(model.head_pos_embed))  # diffusion_pos_embed_learned
    assert max_conditioning_error(model, fixture_arrays) > 1e-4


def test_factory_heads_and_unknown_factories():
    with pytest.raises(ConfigError, match=r"timar_tiny_b.*--heads N"):
        official.load_official(CHECKPOINT)
    cfg = official.load_official(CHECKPOINT, heads=HEADS)[0].cfg
    assert (cfg.dim, cfg.depth, cfg.heads, cfg.token_dim, cfg.speech_dim, cfg.max_turns) == (24, 3, 3, 40, 24, 8)
    assert (cfg.head_width, cfg.head_blocks, cfg.motion_norm, cfg.sampling_steps) == (40, 3, "none", 5)
    assert official.FACTORY_HEADS == {"timar_base": 12, "timar_large": 16, "timar_huge": 16}


def test_every_turn_nulling_is_a_named_option_that_moves_the_unconditional_branch(monkeypatch, fixture_arrays):
    inputs, outputs = fixture_arrays
    monkeypatch.setitem(official.FACTORY_HEADS, "timar_tiny_b", HEADS)
    stream = build_timar(ModelOptions(weights=CHECKPOINT, cfg_scale=3.0, extra={
        "wav2vec_weights": str(WAV2VEC), "cache": False, "guidance_null": "every-turn"}))
    seen = []
    monkeypatch.setattr(stream.model, "sample_frames", lambda z, *a, **k: seen.append(z) or torch.zeros(F, 56))
    stream_agent(stream, fixture_clip(inputs), "speaker2", ProtocolConfig(context=7, speech_norm="clip"))
    z = torch.stack(seen).double().numpy()
    assert np.abs(z[0, 1] - outputs["z_uncond"][0]).max() < 1e-5  # one turn: the same tokens are nulled
    assert np.abs(z[:, 1] - outputs["z_uncond"]).max() > 0.1
    assert stream.info.config["guidance_null"] == "every-turn" and stream.info.version.endswith("+null-every-turn")
