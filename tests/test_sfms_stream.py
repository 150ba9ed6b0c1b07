"""SFMS through the streaming protocol: checkpoint round trip, factory, causality, determinism."""

import numpy as np
import pytest
import torch

from dyadbench.errors import InputError
from dyadbench.protocol.causality import check_causal, perturb_after
from dyadbench.protocol.config import ProtocolConfig
from dyadbench.protocol.interface import ModelOptions
from dyadbench.protocol.streaming import stream_agent
from dyadbench.synth.corpus import make_clips
from dyadbench.training.checkpoint import save_checkpoint
from models.sfms.bundle import SFMS, PREDICTOR_MODEL, load_sfms, load_tokenizer
from models.sfms.config import predictor_preset, tokenizer_preset
from models.sfms.infer import Roller, roll
from models.sfms.predictor import SFMSPredictor
from models.sfms.registry import build_sfms
from models.sfms.tokenizer import SFMSTokenizer

torch.set_num_threads(1)


@pytest.fixture(scope="module")
def weights(tmp_path_factory):
    torch.manual_seed(0)
    tok = SFMSTokenizer(tokenizer_preset("tiny", width=32, heads=2, ffn=64, pe_dim=8))
    tok.motion_mean.fill_(0.1)
    tok.motion_std.fill_(0.5)
    pred = SFMSPredictor(predictor_preset("tiny", width=32, heads=2, ffn=64, audio_bins=8), 56, tok.cfg.n_classes)
    for block in pred.fusion:
        block.alpha.data.fill_(0.3)  # make the audio path count (it starts at 0)
    model = SFMS(tok, pred).eval()
    path = tmp_path_factory.mktemp("sfms") / "sfms.pt"
    save_checkpoint(path, model_state=model.state_dict(), config=model.config(), meta={"model": PREDICTOR_MODEL})
    return path


@pytest.fixture(scope="module")
def clip():
    return make_clips("test", 1, duration_s=5.0)[0]


def test_checkpoint_round_trip_gives_identical_outputs(weights):
    model, meta = load_sfms(weights)
    assert meta["model"] == "sfms"
    again, _ = load_sfms(weights)
    for a, b in zip(model.state_dict().values(), again.state_dict().values()):
        assert torch.equal(a, b)
    assert float(load_tokenizer(weights).motion_std[0]) == pytest.approx(0.5)
    speaker = torch.randn(2, 60, 56)
    audio = torch.randn(2, 240, 8)
    outs = [roll(Roller(m), speaker, audio, 0, 60, torch.Generator().manual_seed(3)) for m in (model, again)]
    assert torch.equal(outs[0], outs[1])


def test_factory_loads_weights_and_records_config(weights):
    model = build_sfms(ModelOptions(weights=weights))
    assert model.info.name == "sfms" and model.info.weights_digest
    assert model.info.config["tokenizer"]["keyframes"] == 10
    assert model.info.config["predictor"]["speaker_span"] == "concurrent"


def test_factory_missing_weights_says_how_to_train(tmp_path):
    with pytest.raises(InputError, match="dyadbench train sfms"):
        build_sfms(ModelOptions(weights=tmp_path / "nope.pt"))


def test_streams_finite_motion_deterministically(weights, clip):
    config = ProtocolConfig(context=2, seed=4)
    outs = [stream_agent(build_sfms(ModelOptions(weights=weights)), clip, "speaker1", config).motion for _ in range(2)]
    assert outs[0].shape == (125, 56) and np.isfinite(outs[0]).all()
    np.testing.assert_array_equal(outs[0], outs[1])
    other = stream_agent(build_sfms(ModelOptions(weights=weights)), clip, "speaker1",
                         ProtocolConfig(context=2, seed=5)).motion
    assert not np.array_equal(outs[0], other)  # multinomial sampling is seeded per stream


@pytest.mark.parametrize("context, turn", [(2, 1), (0, 2)])
def test_causal_through_the_protocol(weights, clip, context, turn):
    check_causal(lambda: build_sfms(ModelOptions(weights=weights)), clip, "speaker2",
                 ProtocolConfig(context=context, seed=1), turn)


def test_partner_input_is_used(weights, clip):
    """Sanity for the causality test: later partner inputs do change later outputs."""
    config = ProtocolConfig(context=2, seed=1)
    a = stream_agent(build_sfms(ModelOptions(weights=weights)), clip, "speaker2", config)
    b = stream_agent(build_sfms(ModelOptions(weights=weights)), perturb_after(clip, 50, agent="speaker2"),
                     "speaker2", config)
    np.testing.assert_array_equal(a.motion[:50], b.motion[:50])
    assert not np.array_equal(a.motion[50:], b.motion[50:])


def test_neutral_start_generation_runs_750_frames(weights):
    model, _ = load_sfms(weights)
    out = roll(Roller(model), torch.zeros(1, 750, 56), torch.zeros(1, 3000, 8), 0, 750,
               torch.Generator().manual_seed(0))
    assert out.shape == (1, 750, 56) and torch.isfinite(out).all()


@pytest.mark.parametrize("dataset, stem", [("synthetic", "sfms-tiny.pt"), ("synthetic-v2", "sfms-tiny-v2.pt")])
def test_shipped_checkpoint_loads_and_records_its_training(dataset, stem):
    model = build_sfms(ModelOptions(dataset=dataset))
    assert model.info.weights_path.endswith(stem)
    meta = model.info.config["train_meta"]
    assert meta["model"] == "sfms" and meta["data"]["dataset"] == dataset and meta["seed"] == 0
    assert model.info.config["tokenizer"]["keyframe_mode"] == "dynamic"
    assert meta["best_val_ce"] < meta["val"][-1]["unigram_ce"]  # beats the class-frequency predictor
