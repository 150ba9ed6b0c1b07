"""Batched streaming (``stream_agents`` / ``--batch``): the same predictions as streaming one direction at a
time, for every registered streaming model, streams of unequal lengths, n = 0 and n = 7, caches on."""

from __future__ import annotations

import numpy as np
import pytest

from dyadbench.datasets.base import InMemorySource
from dyadbench.errors import ConfigError, InputError
from dyadbench.protocol.causality import check_causal
from dyadbench.protocol.config import ProtocolConfig
from dyadbench.protocol.interface import ModelInfo, ModelOptions, StreamingModel, TurnInput
from dyadbench.protocol.runner import evaluate
from dyadbench.protocol.streaming import stream_agent, stream_agents
from dyadbench.registry import MODELS
from tests.protocol_clips import isolated_cache, make_clip, make_source  # noqa: F401

#: Models whose batched forward passes group several streams' rows: their arithmetic may round differently
#: from one stream's (a different matrix-product blocking); everything else must be bit for bit.
BATCHED_ARITHMETIC = {"timar", "timar-stream", "dualtalk"}
#: |batched - one at a time| allowed for them, in motion units (coefficients of order 1).
TOLERANCE = 1e-4


@pytest.fixture(autouse=True, scope="module")
def one_thread():
    """One torch thread: on a shared machine a second thread per process makes these small models many times
    slower (its waits spin); the previous setting is restored."""
    torch = pytest.importorskip("torch")
    before = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(before)


def _streaming_models() -> list[str]:
    return [name for name in MODELS.names() if not name.endswith("-offline")]


def _setting(name: str, seconds: tuple[float, ...]):
    """Clips of unequal lengths in the model's layout (gaze models: single-participant gaze7) and options."""
    gaze = "gaze" in MODELS.get(name).tags
    layout, people = ("gaze7", 1) if gaze else ("flame56", 2)
    train = make_source(3, split="train", seed=11, seconds=6.0, layout=layout, participants=people)
    clips = [make_clip(f"u{i}", s, seed=20 + i, layout=layout, participants=people) for i, s in enumerate(seconds)]
    options = ModelOptions(seed=0, train_split=lambda: train, extra={"layout": layout, "turn_seconds": 1.0})
    return clips, options


def _assert_same(name: str, batched: np.ndarray, alone: np.ndarray) -> None:
    if name in BATCHED_ARITHMETIC:
        np.testing.assert_allclose(batched, alone, rtol=0, atol=TOLERANCE)
    else:
        np.testing.assert_array_equal(batched, alone)


@pytest.mark.parametrize("name", _streaming_models())
@pytest.mark.parametrize("context", [0, 7])
def test_batched_streams_equal_streaming_one_at_a_time(name, context):
    # 9.4 s: the n = 7 window slides (batched models); a short clip ends early and hands its slot on; 3 slots
    # for 6 directions. Models that loop over the batch (the default) stream shorter clips.
    clips, options = _setting(name, (9.4, 2.2, 4.0) if name in BATCHED_ARITHMETIC else (3.4, 1.2, 2.0))
    build = MODELS.load(name)
    if not isinstance(build(options), StreamingModel):
        pytest.skip(f"{name} is an offline model")
    config = ProtocolConfig(context=context, seed=3)
    directions = [(clip, p.name) for clip in clips for p in clip.agent_participants]
    alone = [stream_agent(build(options), clip, agent, config) for clip, agent in directions]
    batched = list(stream_agents(build(options), directions, config, batch=3))
    assert [b.stem for b in batched] == [a.stem for a in alone]
    for a, b in zip(alone, batched):
        assert b.motion.shape == a.motion.shape and len(b.turn_latency_s) == a.num_turns
        _assert_same(name, b.motion, a.motion)


@pytest.mark.parametrize("name", ["timar", "timar-stream"])
@pytest.mark.parametrize("cache", [True, False])
@pytest.mark.parametrize("cfg_scale", [1.0, 2.0])
def test_timar_batches_with_and_without_cache_and_guidance(name, cache, cfg_scale):
    clips, _ = _setting(name, (9.0, 3.0))
    options = ModelOptions(cfg_scale=cfg_scale, extra={"cache": cache, "layout": "flame56", "turn_seconds": 1.0})
    build = MODELS.load(name)
    config = ProtocolConfig(context=2)
    directions = [(clip, p.name) for clip in clips for p in clip.agent_participants]
    alone = [stream_agent(build(options), clip, agent, config).motion for clip, agent in directions]
    batched = [out.motion for out in stream_agents(build(options), directions, config, batch=4)]
    for a, b in zip(alone, batched):
        np.testing.assert_allclose(b, a, rtol=0, atol=TOLERANCE)


@pytest.mark.parametrize("name", _streaming_models())
def test_causality_holds_with_batching(name):
    clips, options = _setting(name, (5.0,))
    build = MODELS.load(name)
    if not isinstance(build(options), StreamingModel):
        pytest.skip(f"{name} is an offline model")
    check_causal(lambda: build(options), clips[0], clips[0].participants[0].name, ProtocolConfig(context=2), 1,
                 batched=True)


class _Counter(StreamingModel):
    """Output = turn index + stream offset; counts calls and the turns of each."""

    info = ModelInfo(name="counter")

    def __init__(self):
        self.calls: list[list[tuple[int, int]]] = []
        self.offset = 0.0

    def start_stream(self, ctx):
        self.offset = float(ctx.num_turns)

    def predict_turn(self, turn: TurnInput) -> np.ndarray:
        return np.full((turn.frames_per_turn, 56), turn.turn + 100 * self.offset, np.float32)

    def predict_turns(self, turns):
        self.calls.append([(t.stream, t.turn) for t in turns])
        return super().predict_turns(turns)


def test_slots_refill_in_order_and_outputs_come_back_in_order():
    clips = [make_clip(f"c{i}", s, seed=i) for i, s in enumerate((3.0, 1.0, 2.0))]
    directions = [(clip, "speaker1") for clip in clips]
    model = _Counter()
    outs = list(stream_agents(model, directions, ProtocolConfig(context=1), batch=2))
    assert [o.stem for o in outs] == ["c0_speaker1", "c1_speaker1", "c2_speaker1"]
    # slot 1 streams c1 (1 turn), then c2 (2 turns) from the next call on; slot 0 streams c0 (3 turns)
    assert model.calls == [[(0, 0), (1, 0)], [(0, 1), (1, 0)], [(0, 2), (1, 1)]]
    for out, clip in zip(outs, clips):
        turns = clip.num_frames // 25
        expected = np.repeat(np.arange(turns) + 100.0 * turns, 25)
        np.testing.assert_array_equal(out.motion[:, 0], expected)


def test_batch_larger_than_the_directions_and_bad_batches():
    clip = make_clip("c", 2.0)
    outs = list(stream_agents(_Counter(), [(clip, "speaker1"), (clip, "speaker2")], ProtocolConfig(), batch=8))
    assert [o.stem for o in outs] == ["c_speaker1", "c_speaker2"]
    with pytest.raises(ConfigError, match="batch must be >= 1"):
        list(stream_agents(_Counter(), [(clip, "speaker1")], ProtocolConfig(), batch=0))

    class Short(_Counter):
        def predict_turns(self, turns):
            return super().predict_turns(turns)[:1]

    with pytest.raises(InputError, match="1 outputs for 2 turns"):
        list(stream_agents(Short(), [(clip, "speaker1"), (clip, "speaker2")], ProtocolConfig(), batch=2))


def test_default_copies_do_not_keep_each_other():
    model = _Counter()
    clip = make_clip("c", 2.0)
    list(stream_agents(model, [(clip, "speaker1"), (clip, "speaker2")], ProtocolConfig(), batch=2))
    copies = model.__dict__["_slot_models"]
    assert set(copies) == {0, 1} and all("_slot_models" not in c.__dict__ for c in copies.values())


@pytest.mark.parametrize("name", ["timar", "mean-frame"])
def test_eval_with_batch_records_the_same_predictions_metrics_and_configuration(name, tmp_path):
    clips = [make_clip(f"c{i}", s, seed=i) for i, s in enumerate((6.2, 3.0, 4.4))]
    source = InMemorySource(clips, dataset="handmade", split="test")
    train = make_source(3, split="train", seed=11, seconds=6.0)
    config = ProtocolConfig(context=7)
    results = {}
    for batch in (1, 4):
        options = ModelOptions(train_split=lambda: train)
        results[batch] = evaluate(name, source, config, options=options, predictions_dir=tmp_path / str(batch),
                                  progress=False, batch=batch)
    one, many = results[1], results[4]
    assert one.configuration == many.configuration and "batch" not in one.configuration
    for path in sorted((tmp_path / "1").glob("*.npy")):
        _assert_same(name, np.load(tmp_path / "4" / path.name), np.load(path))
    if name not in BATCHED_ARITHMETIC:
        assert one.metrics == many.metrics


def _sfms_weights(sharing: str, folder) -> str:
    """A small random SFMS of either keyframe allocation (the channel one has per-channel classes)."""
    torch = pytest.importorskip("torch")
    from dyadbench.training.checkpoint import save_checkpoint  # noqa: PLC0415
    from models.sfms.bundle import PREDICTOR_MODEL, SFMS  # noqa: PLC0415
    from models.sfms.config import predictor_preset, tokenizer_preset  # noqa: PLC0415
    from models.sfms.predictor import SFMSPredictor  # noqa: PLC0415
    from models.sfms.tokenizer import SFMSTokenizer  # noqa: PLC0415

    torch.manual_seed(0)
    tok = SFMSTokenizer(tokenizer_preset("tiny", width=32, heads=2, ffn=64, pe_dim=8, keyframes=4,
                                         mask_sharing=sharing))
    pred = SFMSPredictor(predictor_preset("tiny", width=32, heads=2, ffn=64, audio_bins=8), 56, tok.cfg.n_classes,
                         tok.cfg.per_channel)
    for block in pred.fusion:
        block.alpha.data.fill_(0.3)
    path = folder / f"sfms-{sharing}.pt"
    model = SFMS(tok, pred).eval()
    save_checkpoint(path, model_state=model.state_dict(), config=model.config(), meta={"model": PREDICTOR_MODEL})
    return str(path)


@pytest.mark.parametrize("sharing", ["shipped", "frame", "channel"])
@pytest.mark.parametrize("context", [0, 7])
def test_sfms_batches_its_steps_and_equals_streaming_one_at_a_time(sharing, context, tmp_path, monkeypatch):
    """SFMS runs the open streams' steps as one batch (the roller sees B > 1) with per-stream caches and random
    draws: outputs equal streaming each direction alone, bit for bit, for streams of unequal lengths (a clip
    ending early hands its slot on) and a clip at another frame rate (its own group). Per-channel allocation
    runs its streams one at a time (a batch of its tokens rounds differently) and is bit for bit too."""
    from models.sfms.infer import Roller  # noqa: PLC0415

    weights = None if sharing == "shipped" else _sfms_weights(sharing, tmp_path)
    options = ModelOptions(seed=0, weights=weights, extra={"layout": "flame56", "turn_seconds": 1.0})
    clips = [make_clip(f"u{i}", s, seed=30 + i) for i, s in enumerate((9.4, 2.2, 4.0))]
    clips.append(make_clip("u20fps", 3.0, seed=40, fps=20.0))
    directions = [(clip, p.name) for clip in clips for p in clip.agent_participants]
    build = MODELS.load("sfms")
    config = ProtocolConfig(context=context, seed=3)
    alone = [stream_agent(build(options), clip, agent, config) for clip, agent in directions]
    sizes = []
    step = Roller.step

    def counted(self, hist, *args, **kwargs):
        sizes.append(hist.shape[0])
        return step(self, hist, *args, **kwargs)

    monkeypatch.setattr(Roller, "step", counted)
    batched = list(stream_agents(build(options), directions, config, batch=5))
    # the five open streams in one batch (the 20 fps clip's turns in a group of their own); channel: one by one
    assert max(sizes) == (1 if sharing == "channel" else 5)
    assert [b.stem for b in batched] == [a.stem for a in alone]
    for a, b in zip(alone, batched):
        np.testing.assert_array_equal(b.motion, a.motion)
