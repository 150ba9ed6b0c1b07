"""StyGazeTalk batched streaming (``predict_turns`` / ``--batch``): several streams' windows in one forward
pass, each stream with its own track and generator, bit for bit the predictions of streaming each session
alone — shipped weights (sampled eye decoding, X1) and a random model (mean decoding), n = 0 and n = 7,
sessions of unequal lengths, other turn lengths, style transfer and the MPGW-sim seed; causality with
batching; ``dyadbench eval``'s path with ``batch`` > 1 reaching the batched generator."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from dyadbench.datasets.base import InMemorySource
from dyadbench.protocol.causality import check_causal
from dyadbench.protocol.config import ProtocolConfig
from dyadbench.protocol.interface import ModelOptions
from dyadbench.protocol.runner import evaluate
from dyadbench.protocol.streaming import stream_agent, stream_agents
from dyadbench.synth.gaze import make_gaze_session
from models.stygazetalk.checkpoints import save_system, system_from_style
from models.stygazetalk.config import get_generator_config, get_style_config
from models.stygazetalk.generator import LSTMCore, MotionGenerator
from models.stygazetalk.registry import build_stygazetalk
from models.stygazetalk.train_style import StyleModel

AGENT = "subject"


@pytest.fixture(autouse=True, scope="module")
def one_thread():
    """One torch thread (the shared-machine setting of the other streaming tests); restored afterwards."""
    before = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(before)


@pytest.fixture(scope="module")
def sessions():
    """Sessions of unequal lengths: 11.2 s (11 turns, 9 generated), 3 s (seed turns and one generated),
    2 s (seed turns only), 7.6 s and 5 s: with three slots, short sessions hand their slot on while
    others are mid-stream, so calls mix seed turns and generated turns of streams at different turns."""
    return [make_gaze_session("test", i, seed=0, duration_s=s) for i, s in enumerate((11.2, 3.0, 2.0, 7.6, 5.0))]


@pytest.fixture(scope="module")
def random_weights(tmp_path_factory):
    """A random SE-64 model with visibly input-dependent outputs and mean decoding (not the shipped weights)."""
    torch.manual_seed(1)
    cfg = get_generator_config("tiny-se64")
    style = StyleModel(get_style_config("tiny-se64"))
    style.motion_norm.mean.copy_(torch.linspace(-1, 1, 7))
    style.motion_norm.std.copy_(torch.full((7,), 3.0))
    system = system_from_style(cfg, style)
    for p in system.generator.parameters():
        p.data.mul_(3.0)
    system.residual_pool.copy_(0.3 * torch.randn(system.residual_pool.shape))
    return save_system(tmp_path_factory.mktemp("sgt-batched") / "se64.pt", system.eval(), {"seed": 1})


class _LSTMBatches:
    """Records the batch sizes the LSTM core sees (to show the batch really reaches the forward pass)."""

    def __init__(self, monkeypatch):
        self.sizes: list[int] = []
        forward = LSTMCore.forward

        def counted(core, z, state):
            self.sizes.append(z.shape[0])
            return forward(core, z, state)

        monkeypatch.setattr(LSTMCore, "forward", counted)


def _alone_and_batched(options: ModelOptions, sessions, config: ProtocolConfig, batch: int, monkeypatch):
    directions = [(clip, AGENT) for clip in sessions]
    alone = [stream_agent(build_stygazetalk(options), clip, agent, config) for clip, agent in directions]
    seen = _LSTMBatches(monkeypatch)
    batched = list(stream_agents(build_stygazetalk(options), directions, config, batch))
    assert [b.stem for b in batched] == [a.stem for a in alone]
    return alone, batched, seen.sizes


@pytest.mark.parametrize("weights", ["shipped", "random"])
@pytest.mark.parametrize("context", [0, 7])
def test_batched_streams_equal_streaming_each_session_alone(weights, context, sessions, random_weights,
                                                            monkeypatch):
    options = ModelOptions(seed=0, weights=None if weights == "shipped" else random_weights)
    alone, batched, sizes = _alone_and_batched(options, sessions, ProtocolConfig(context=context, seed=3), 3,
                                               monkeypatch)
    assert max(sizes) == 3  # three streams generating in one LSTM step
    for a, b in zip(alone, batched):
        assert b.motion.shape == a.motion.shape and len(b.turn_latency_s) == a.num_turns
        np.testing.assert_array_equal(b.motion, a.motion)
    # the sessions differ from each other after the seed (no stream read another's inputs or state)
    assert not np.allclose(batched[0].motion[50:75], batched[3].motion[50:75])


@pytest.mark.parametrize("turn_seconds", [0.4, 2.0])
def test_other_turn_lengths_batch_bit_for_bit(turn_seconds, sessions, random_weights, monkeypatch):
    """10-frame turns (a window every turn, 10 of its 25 frames kept) and 50-frame turns (two windows per turn,
    the second reading the first's frames)."""
    options = ModelOptions(seed=0, weights=random_weights, extra={"decoding": "sample"})
    config = ProtocolConfig(context=2, seed=1, turn_seconds=turn_seconds)
    alone, batched, sizes = _alone_and_batched(options, sessions, config, 4, monkeypatch)
    assert max(sizes) >= 3
    for a, b in zip(alone, batched):
        np.testing.assert_array_equal(b.motion, a.motion)


@pytest.mark.parametrize("extra", [{"seed_window": "mpgw-sim"}, {"style_from": "session"}])
def test_style_transfer_and_mpgw_seed_batch_bit_for_bit(extra, sessions, random_weights, monkeypatch):
    if "style_from" in extra:
        extra = {"style_from": make_gaze_session("test", 7, seed=0, duration_s=6.0).participants[0].motion}
    options = ModelOptions(seed=2, weights=random_weights, extra=extra)
    alone, batched, _ = _alone_and_batched(options, sessions, ProtocolConfig(context=7, seed=2), 5, monkeypatch)
    for a, b in zip(alone, batched):
        np.testing.assert_array_equal(b.motion, a.motion)


@pytest.mark.parametrize("config", ["tiny-se64", "tiny-tfm-se64", "tiny-base"])
def test_generate_blocks_rows_equal_generate_block_alone(config):
    """Row b of a batch of windows is bit for bit its own window's generate_block, draws included (random
    inputs, batches of 2 to 6 rows; the Transformer backbone and the style-free Base variant too)."""
    torch.manual_seed(0)
    cfg = get_generator_config(config)
    gen = MotionGenerator(cfg, 32).eval()
    for p in gen.parameters():
        p.data.mul_(2.0)
    pool = torch.randn(64, 7)

    def drawer(seed: int):
        rng = torch.Generator().manual_seed(seed)
        return lambda mean: mean + pool[torch.randint(64, mean.shape[:-1], generator=rng)]

    with torch.no_grad():
        for rows in (2, 3, 6):
            audio = torch.randn(rows, cfg.window, 32)
            known = torch.randn(rows, cfg.warmup + 1, 7)
            style = torch.randn(rows, cfg.style_dim) if cfg.style else None
            seeds = [int(s) for s in torch.randint(1000, (rows,))]
            together = gen.generate_blocks(audio, known, style, [drawer(s) for s in seeds])
            alone = [gen.generate_block(audio[b:b + 1], known[b:b + 1], None if style is None else style[b:b + 1],
                                        drawer(s)) for b, s in enumerate(seeds)]
            assert together.shape == (rows, cfg.horizon, 7)
            for b in range(rows):
                assert torch.equal(together[b:b + 1], alone[b]), (config, rows, b)
            means = gen.generate_blocks(audio, known, style, [None] * rows)
            assert not torch.equal(means, together)  # the draws are applied, per row
    with pytest.raises(ValueError, match="one draw per row"):
        gen.generate_blocks(audio, known, style, [None])


def test_causality_holds_with_batching(sessions, random_weights):
    """The original and a perturbed copy stream through one model in one batch (``check_causal(batched=True)``):
    perturbing the future of turn 4 changes nothing before it, after the seed window too."""
    options = ModelOptions(seed=0, weights=random_weights, extra={"decoding": "sample"})
    for turn in (1, 4):
        check_causal(lambda: build_stygazetalk(options), sessions[0], AGENT, ProtocolConfig(context=3), turn,
                     batched=True)


def test_eval_with_batch_reaches_the_batched_generator_and_scores_the_same(sessions, tmp_path, monkeypatch):
    """``evaluate`` (what ``dyadbench eval --batch`` runs) on gaze sessions: the model's LSTM sees several
    streams at once, and predictions and every metric equal the batch-1 run."""
    source = InMemorySource(sessions, dataset="handmade-gaze", split="test")
    results = {}
    for batch in (1, 4):
        seen = _LSTMBatches(monkeypatch)
        results[batch] = evaluate("stygazetalk", source, ProtocolConfig(context=7), options=ModelOptions(seed=0),
                                  predictions_dir=tmp_path / str(batch), progress=False, batch=batch)
        assert (max(seen.sizes) > 1) == (batch > 1)  # batch 4: several streams' windows in one LSTM step
        monkeypatch.undo()
    assert results[1].suite == "gaze" and results[1].configuration == results[4].configuration
    for path in sorted((tmp_path / "1").glob("*.npy")):
        np.testing.assert_array_equal(np.load(tmp_path / "4" / path.name), np.load(path))
    assert results[1].metrics == results[4].metrics
