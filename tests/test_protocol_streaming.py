"""The streaming protocol: turn slicing, history, tails, read-only inputs, oracle gating, seeds."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from dyadbench.errors import ConfigError, InputError
from dyadbench.protocol.causality import CausalityViolation, check_causal
from dyadbench.protocol.config import ProtocolConfig
from dyadbench.protocol.interface import ModelInfo, OfflineModel, StreamContext, StreamingModel, TurnInput
from dyadbench.protocol.runner import run_direction
from dyadbench.protocol.streaming import stream_agent
from dyadbench.seeding import derive_seed
from tests.protocol_clips import isolated_cache, make_clip  # noqa: F401


class Spy(StreamingModel):
    """Records what it is given; outputs the mean of the current user motion (or zeros)."""

    def __init__(self, oracle: bool = False, dim: int = 56):
        self.info = ModelInfo("spy", oracle=oracle)
        self.dim = dim
        self.turns: list[TurnInput] = []
        self.ctx: StreamContext | None = None

    def start_stream(self, ctx: StreamContext) -> None:
        self.ctx = ctx
        self.turns = []

    def predict_turn(self, turn: TurnInput) -> np.ndarray:
        self.turns.append(turn)
        return np.full((turn.frames_per_turn, self.dim), float(turn.turn), np.float32)


@pytest.mark.parametrize("kwargs", [dict(context=-1), dict(context=1.5), dict(tail="pad"),
                                    dict(history_agent="gt"), dict(turn_seconds=0), dict(turn_seconds="x"),
                                    dict(seed="0")])
def test_config_rejects_bad_values(kwargs):
    with pytest.raises(ConfigError):
        ProtocolConfig(**kwargs)


def test_turn_must_hold_whole_frames_and_samples():
    assert ProtocolConfig(turn_seconds=1.0).frames_per_turn(25.0) == 25
    assert ProtocolConfig(turn_seconds=0.4).samples_per_turn(16_000) == 6400
    with pytest.raises(ConfigError, match="whole number"):
        ProtocolConfig(turn_seconds=0.03).frames_per_turn(25.0)


@pytest.mark.parametrize("context", [0, 1, 3, 7])
def test_windows_hold_min_t_n_history_turns_of_exact_ground_truth(context):
    clip = make_clip("w", 6.0)
    spy = Spy()
    stream_agent(spy, clip, "speaker1", ProtocolConfig(context=context))
    user, agent = clip.participant("speaker2"), clip.participant("speaker1")
    assert [t.turn for t in spy.turns] == list(range(6))
    for t in spy.turns:
        h = min(t.turn, context)
        assert t.history_turns == h
        f0, f1, s0, s1 = (t.turn - h) * 25, (t.turn + 1) * 25, (t.turn - h) * 16000, (t.turn + 1) * 16000
        np.testing.assert_array_equal(t.user_motion, user.motion[f0:f1])
        np.testing.assert_array_equal(t.user_audio, user.audio[s0:s1])
        np.testing.assert_array_equal(t.agent_audio, agent.audio[s0:s1])
        np.testing.assert_array_equal(t.current_user_motion, user.motion[t.turn * 25:f1])
        assert t.agent_history is None and t.agent_motion_oracle is None


def test_inputs_are_read_only_copies_that_cannot_reach_the_clip():
    clip = make_clip("ro", 3.0)
    spy = Spy()
    stream_agent(spy, clip, "speaker2", ProtocolConfig(context=1))
    for t in spy.turns:
        for arr in (t.user_motion, t.user_audio, t.agent_audio):
            assert not arr.flags.writeable
            assert arr.base is None  # an owned copy: no view of the whole clip to walk back to
            for p in clip.participants:
                assert not np.shares_memory(arr, p.motion) and not np.shares_memory(arr, p.audio)
        with pytest.raises(ValueError):
            t.user_motion[0, 0] = 1.0


@pytest.mark.parametrize("seconds,tail,frames", [(4.4, "truncate", 100), (4.4, "pad-last", 110),
                                                  (4.0, "truncate", 100), (4.0, "pad-last", 100)])
def test_tail_truncate_and_pad_last_lengths(seconds, tail, frames):
    clip = make_clip("t", seconds)
    out = stream_agent(Spy(), clip, "speaker1", ProtocolConfig(tail=tail))
    assert out.motion.shape == (frames, 56)
    assert out.num_turns == 4 and out.tail_frames == frames - 100
    np.testing.assert_array_equal(out.motion[100:], np.repeat(out.motion[99:100], frames - 100, axis=0))
    assert len(out.turn_latency_s) == 4 and all(x >= 0 for x in out.turn_latency_s)


def test_history_outputs_policy_hands_back_earlier_outputs():
    spy = Spy()
    stream_agent(spy, make_clip("h", 5.0), "speaker1", ProtocolConfig(context=2, history_agent="outputs"))
    for t in spy.turns:
        h = t.history_turns
        assert t.agent_history.shape == (h * 25, 56)
        expected = np.concatenate([np.full((25, 56), k, np.float32) for k in range(t.turn - h, t.turn)] or
                                  [np.zeros((0, 56), np.float32)])
        np.testing.assert_array_equal(t.agent_history, expected)
        assert not t.agent_history.flags.writeable


def test_only_oracle_models_receive_ground_truth():
    clip = make_clip("o", 3.0)
    oracle = Spy(oracle=True)
    stream_agent(oracle, clip, "speaker1", ProtocolConfig(context=1))
    for t in oracle.turns:
        h = t.history_turns
        np.testing.assert_array_equal(t.agent_motion_oracle,
                                      clip.participant("speaker1").motion[(t.turn - h) * 25:(t.turn + 1) * 25])
    plain = Spy()
    stream_agent(plain, clip, "speaker1", ProtocolConfig(context=1))
    assert all(t.agent_motion_oracle is None for t in plain.turns)


def test_single_participant_sessions_stream_with_empty_user_arrays():
    clip = make_clip("g", 2.2, participants=1, layout="gaze7")
    spy = Spy(dim=7)
    out = stream_agent(spy, clip, "speaker1", ProtocolConfig(context=3))
    assert out.motion.shape == (50, 7)
    assert spy.ctx.user is None
    for t in spy.turns:
        assert t.user_motion.shape == ((t.history_turns + 1) * 25, 0) and t.user_audio.shape == (0,)
        assert t.current_user_audio.shape == (0,)


def _with_features(clip, rows: int = 4, bins: int = 6):
    """``clip`` with speech features (T·rows, bins) on its second participant only."""
    p1, p2 = clip.participants
    feats = np.arange(p2.motion.shape[0] * rows * bins, dtype=np.float32).reshape(-1, bins)
    return replace(clip, participants=(p1, replace(p2, speech_features=feats)))


def test_speech_features_are_sliced_like_the_motion():
    clip = _with_features(make_clip("f", 3.0))
    feats = clip.participant("speaker2").speech_features
    spy = Spy()
    stream_agent(spy, clip, "speaker1", ProtocolConfig(context=1))
    for t in spy.turns:
        f0, f1 = (t.turn - t.history_turns) * 25, (t.turn + 1) * 25
        np.testing.assert_array_equal(t.user_speech_features, feats[f0 * 4:f1 * 4])
        np.testing.assert_array_equal(t.current_user_speech_features, feats[t.turn * 100:f1 * 4])
        assert not t.user_speech_features.flags.writeable and t.user_speech_features.base is None
        assert t.agent_speech_features is None
    stream_agent(spy, clip, "speaker2", ProtocolConfig(context=0))
    assert all(t.user_speech_features is None and t.agent_speech_features.shape == (100, 6) for t in spy.turns)


def test_causality_checker_perturbs_speech_features(monkeypatch):
    class ReadsNextFeatures(Spy):
        def predict_turn(self, turn):  # leaks one turn of features past the current one, via the clip
            stop = (turn.turn + 2) * 100
            ahead = self.clip_feats[stop - 100:stop]
            return np.full((25, 56), float(ahead.sum()) if len(ahead) == 100 else 0.0, np.float32)

    clip = _with_features(make_clip("cf", 4.0))
    check_causal(Spy, clip, "speaker1", ProtocolConfig(context=1), 1)  # reads its sliced features only
    import dyadbench.protocol.causality as causality

    original = causality.stream_agent

    def recording(model, c, a, config):
        model.clip_feats = c.participant("speaker2").speech_features
        return original(model, c, a, config)

    monkeypatch.setattr(causality, "stream_agent", recording)
    with pytest.raises(CausalityViolation):
        check_causal(ReadsNextFeatures, clip, "speaker1", ProtocolConfig(context=1), 1)


@pytest.mark.parametrize("shape, match", [((99, 6), "whole rows"), ((50, 6), "whole rows"), ((100,), "whole rows")])
def test_bad_speech_features_are_named(shape, match):
    p1, p2 = make_clip("bf", 4.0).participants  # 100 frames
    with pytest.raises(InputError, match=match) as err:
        type(make_clip("bf"))("bf", (p1, replace(p2, speech_features=np.zeros(shape, np.float32))))
    assert "bf_speaker2" in str(err.value)


def test_clip_agents_choose_the_generated_directions():
    clip = replace(make_clip("ag", 2.0), agents=("speaker2",))
    assert clip.agent_ids() == ["ag_speaker2"] and [p.name for p in clip.agent_participants] == ["speaker2"]
    with pytest.raises(InputError, match="agents must name participants"):
        replace(clip, agents=("listener",))


def test_short_audio_is_zero_padded():
    clip = make_clip("a", 3.0)
    p1, p2 = clip.participants
    short = type(p1)(p1.name, p1.motion, p1.audio[:40_000], p1.identity)
    clip = type(clip)("a", (short, p2))
    spy = Spy()
    stream_agent(spy, clip, "speaker1", ProtocolConfig(context=0))
    last = spy.turns[-1].agent_audio
    assert last.shape == (16000,)
    np.testing.assert_array_equal(last[8000:], 0.0)
    np.testing.assert_array_equal(last[:8000], p1.audio[32000:40000])


def test_stream_seed_is_derived_from_run_seed_clip_and_agent():
    clip = make_clip("s", 2.0)
    seeds = {}
    for agent in ("speaker1", "speaker2"):
        spy = Spy()
        stream_agent(spy, clip, agent, ProtocolConfig(seed=7))
        seeds[agent] = spy.ctx.seed
        assert spy.ctx.seed == derive_seed(7, "s", agent)
        assert spy.ctx.agent_identity == clip.participant(agent).identity
    assert seeds["speaker1"] != seeds["speaker2"]


class Bad(StreamingModel):
    def __init__(self, out):
        self.info = ModelInfo("bad")
        self.out = out

    def predict_turn(self, turn):
        return self.out


@pytest.mark.parametrize("out,match", [(np.zeros((24, 56)), "shape"), (np.full((25, 56), np.nan), "non-finite"),
                                       (np.zeros((25, 55)), "shape")])
def test_bad_model_output_is_named(out, match):
    with pytest.raises(InputError, match=match) as exc:
        stream_agent(Bad(out), make_clip("b", 2.0), "speaker1", ProtocolConfig())
    assert "bad on b_speaker1, turn 0" in str(exc.value)


def test_clip_shorter_than_a_turn_is_refused():
    with pytest.raises(InputError, match="shorter than one turn"):
        stream_agent(Spy(), make_clip("tiny", 0.6), "speaker1", ProtocolConfig())


def test_unknown_agent_is_named():
    with pytest.raises(InputError, match="no participant 'speaker3'"):
        stream_agent(Spy(), make_clip("u", 2.0), "speaker3", ProtocolConfig())


def test_causality_checker_catches_a_model_reading_the_future(monkeypatch):
    holder = {}
    with pytest.raises(CausalityViolation, match="output up to turn 1 changed"):
        _check_with_holder(monkeypatch, lambda: _FromHolder(holder), holder, make_clip("c", 5.0), "speaker1")


def test_causality_checker_catches_a_non_oracle_reading_ground_truth(monkeypatch):
    holder = {"read_agent": True}
    with pytest.raises(CausalityViolation, match="agent's ground truth"):
        _check_with_holder(monkeypatch, lambda: _FromHolder(holder), holder, make_clip("c", 5.0), "speaker1")


def test_causality_checker_passes_a_causal_model_and_validates_turn():
    clip = make_clip("c", 5.0)
    check_causal(Spy, clip, "speaker1", ProtocolConfig(context=2), 2)
    with pytest.raises(ConfigError, match="turn must be"):
        check_causal(Spy, clip, "speaker1", ProtocolConfig(), 4)


class _FromHolder(StreamingModel):
    """Looks up the clip currently being streamed in a shared dict (a stand-in for a global data leak)."""

    def __init__(self, holder):
        self.info = ModelInfo("leaky")
        self.holder = holder

    def start_stream(self, ctx):
        self.clip = self.holder["clips"][self.holder["calls"]]
        self.holder["calls"] += 1

    def predict_turn(self, turn):
        if self.holder.get("read_agent"):
            return np.asarray(self.clip.participant("speaker1").motion[turn.turn * 25:(turn.turn + 1) * 25])
        stop = (turn.turn + 2) * 25
        future = self.clip.participant("speaker2").motion[stop - 25:stop]
        return np.asarray(future if future.shape[0] == 25 else np.zeros((25, 56)), np.float32)


def _check_with_holder(monkeypatch, factory, holder, clip, agent):
    """Run check_causal while handing each stream's clip (original, then perturbed) to the leaky model."""
    import dyadbench.protocol.causality as causality

    seen = []
    original = causality.stream_agent

    def recording(model, c, a, config):
        seen.append(c)
        holder["clips"], holder["calls"] = seen, len(seen) - 1
        return original(model, c, a, config)

    monkeypatch.setattr(causality, "stream_agent", recording)
    check_causal(factory, clip, agent, ProtocolConfig(context=1), 1)


@settings(max_examples=25, deadline=None)
@given(seconds=st.floats(1.0, 6.0), context=st.integers(0, 8), tail=st.sampled_from(["truncate", "pad-last"]))
def test_lengths_property(seconds, context, tail):
    clip = make_clip("p", seconds)
    out = stream_agent(Spy(), clip, "speaker1", ProtocolConfig(context=context, tail=tail))
    whole = (clip.num_frames // 25) * 25
    assert out.motion.shape[0] == (whole if tail == "truncate" else clip.num_frames)


class FullSequence(OfflineModel):
    """An offline model: the partner's motion reversed in time (needs the future, so it is not causal)."""

    def __init__(self, frames_off: int = 0):
        self.info = ModelInfo("reverse")
        self.frames_off = frames_off

    def predict_clip(self, ctx, user_motion, user_audio, agent_audio):
        assert not user_motion.flags.writeable and not agent_audio.flags.writeable
        assert agent_audio.shape == (round(user_motion.shape[0] * 640),)
        return user_motion[::-1][: user_motion.shape[0] - self.frames_off]


def test_offline_models_get_the_whole_clip_and_are_recorded_as_offline():
    clip = make_clip("off", 4.4)
    out = run_direction(FullSequence(), clip, "speaker1", ProtocolConfig())
    assert out.protocol == "offline" and out.motion.shape == (110, 56) and len(out.turn_latency_s) == 1
    np.testing.assert_array_equal(out.motion, clip.participant("speaker2").motion[::-1])
    with pytest.raises(InputError, match=r"expected \(110, 56\)"):
        run_direction(FullSequence(frames_off=1), clip, "speaker1", ProtocolConfig())
    with pytest.raises(ConfigError, match="not a StreamingModel"):
        check_causal(FullSequence, clip, "speaker1", ProtocolConfig(), 0)
