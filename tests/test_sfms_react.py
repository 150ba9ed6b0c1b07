"""SFMS on REACT (models/sfms/react.py) and REACT's official trivial baselines (baselines/react.py).

The SFMS tests use small randomly initialised models of the REACT variant (25-d emotion features, no
audio branch, D33) and the shipped ``sfms-tiny-react.pt``; the baseline tests check values that follow
from the definitions in ``shared/specs/metrics-react.md``.
"""

from pathlib import Path

import numpy as np
import pytest
import torch

import models.sfms.checkpoints
from baselines import react as react_baselines
from dyadbench.errors import InputError
from dyadbench.metrics import react as suite
from dyadbench.protocol.interface import ModelOptions
from dyadbench.training.checkpoint import save_checkpoint
from models.sfms.bundle import PREDICTOR_MODEL, SFMS
from models.sfms.config import predictor_preset, tokenizer_preset
from models.sfms.predictor import SFMSPredictor
from models.sfms.react import (CHECKPOINT, generate_reactions, load_react_sfms, reaction_seed,
                               to_valid_range)
from models.sfms.registry import build_sfms
from models.sfms.tokenizer import SFMSTokenizer

torch.set_num_threads(1)
SHIPPED = Path(models.sfms.checkpoints.__file__).parent
NAMES = ["Synth/a/speaker1/1", "Synth/b/speaker2/1"]


def _react_sfms(seed: int = 0) -> SFMS:
    torch.manual_seed(seed)
    tok = SFMSTokenizer(tokenizer_preset("tiny", dim=25, width=32, heads=2, ffn=64, pe_dim=8))
    tok.motion_std.fill_(0.3)
    pred = SFMSPredictor(predictor_preset("tiny", width=32, heads=2, ffn=64, speaker_audio="none", audio_bins=1),
                         25, tok.cfg.n_classes)
    return SFMS(tok, pred).eval()


@pytest.fixture(scope="module")
def model():
    return _react_sfms()


@pytest.fixture(scope="module")
def speaker():
    rng = np.random.default_rng(0)
    return rng.random((2, 60, 25)).astype(np.float32)


def test_outputs_have_the_react_shape_and_valid_ranges(model, speaker):
    out = generate_reactions(model, speaker, NAMES, reactions=3, seed=0)
    assert out.shape == (2, 3, 60, 25) and out.dtype == np.float32
    assert np.isfinite(out).all()
    assert (out[..., :15] >= 0).all() and (out[..., :15] <= 1).all()
    assert (out[..., 15:17] >= -1).all() and (out[..., 15:17] <= 1).all()
    assert (out[..., 17:] >= 0).all()
    np.testing.assert_allclose(out[..., 17:].sum(-1), 1.0, atol=1e-5)


def test_to_valid_range_by_hand():
    frame = np.zeros(25, np.float32)
    frame[:3] = [-0.5, 0.4, 1.7]          # AUs -> 0, 0.4, 1
    frame[15:17] = [-2.0, 0.25]           # valence, arousal -> -1, 0.25
    frame[17:21] = [0.6, -0.2, 0.2, 0.0]  # expression: clip at 0, renormalise by 0.8
    out = to_valid_range(frame)
    np.testing.assert_allclose(out[:3], [0.0, 0.4, 1.0])
    np.testing.assert_allclose(out[15:17], [-1.0, 0.25])
    np.testing.assert_allclose(out[17:25], [0.75, 0, 0.25, 0, 0, 0, 0, 0], atol=1e-7)
    uniform = to_valid_range(-np.ones(25, np.float32))
    np.testing.assert_allclose(uniform[17:], 1 / 8)
    with pytest.raises(InputError, match="25 features"):
        to_valid_range(np.zeros((3, 24)))


def test_future_speaker_frames_never_change_earlier_outputs(model, speaker):
    """Speaker frames >= f changed: output frames < 8*floor(f/8) identical (same seeds), later ones not all."""
    f = 30
    changed = speaker.copy()
    changed[:, f:] = np.random.default_rng(1).random(changed[:, f:].shape)
    a = generate_reactions(model, speaker, NAMES, reactions=2, seed=0)
    b = generate_reactions(model, changed, NAMES, reactions=2, seed=0)
    cut = 8 * (f // 8)
    np.testing.assert_array_equal(a[:, :, :cut], b[:, :, :cut])
    assert not np.array_equal(a[:, :, cut:], b[:, :, cut:])


def test_per_reaction_seeds(model, speaker):
    a = generate_reactions(model, speaker, NAMES, reactions=3, seed=0)
    np.testing.assert_array_equal(a, generate_reactions(model, speaker, NAMES, reactions=3, seed=0, batch=1))
    assert not np.array_equal(a[:, 0], a[:, 1]) and not np.array_equal(a[:, 1], a[:, 2])
    assert not np.array_equal(a, generate_reactions(model, speaker, NAMES, reactions=3, seed=1))
    # a reaction depends on (seed, speaker path, r) only: sample 1 alone gives the same reactions
    np.testing.assert_array_equal(a[1:], generate_reactions(model, speaker[1:], NAMES[1:], reactions=3, seed=0))
    assert reaction_seed(0, NAMES[0], 0) != reaction_seed(0, NAMES[0], 1) != reaction_seed(1, NAMES[0], 1)


def test_no_audio_branch_only_with_speaker_audio_none():
    keys = set(_react_sfms().predictor.state_dict())
    assert not any(k.startswith(("audio_conv", "audio_encoder", "fusion")) for k in keys)
    speech = SFMSPredictor(predictor_preset("tiny", width=32, heads=2, ffn=64), 56, 241)
    assert any(k.startswith("audio_conv") for k in speech.state_dict())


def test_shipped_react_checkpoint_loads_and_generates():
    model, meta = load_react_sfms(CHECKPOINT)
    assert CHECKPOINT.parent == SHIPPED and model.tokenizer.cfg.dim == 25
    assert meta["data"]["layout"] == "react25" and model.predictor.cfg.speaker_audio == "none"
    out = generate_reactions(model, np.full((1, 20, 25), 0.2, np.float32), NAMES[:1], reactions=2)
    assert out.shape == (1, 2, 20, 25) and np.isfinite(out).all()


def test_a_checkpoint_of_another_layout_is_refused_naming_the_file(tmp_path):
    flame = SHIPPED / "sfms-tiny-v2.pt"
    with pytest.raises(InputError, match="sfms-tiny-v2.pt.*flame56 motion \\(56 dims\\).*react25"):
        load_react_sfms(flame)
    with pytest.raises(InputError, match="sfms-tiny-react.pt.*react25 motion.*the split is flame56"):
        build_sfms(ModelOptions(weights=str(CHECKPOINT), extra={"layout": "flame56"}))
    # a 25-d checkpoint that does not record the react25 layout is refused too
    path = tmp_path / "unrecorded.pt"
    m = _react_sfms()
    save_checkpoint(path, model_state=m.state_dict(), config=m.config(), meta={"model": PREDICTOR_MODEL})
    with pytest.raises(InputError, match="unrecorded.pt"):
        load_react_sfms(path)
    with pytest.raises(InputError, match="not found"):
        load_react_sfms(tmp_path / "missing.pt")


# --- the official trivial baselines -----------------------------------------------------------------

N, T = 6, 120


@pytest.fixture(scope="module")
def problem():
    rng = np.random.default_rng(3)
    listener = rng.random((N, T, 25)).astype(np.float32)
    listener[..., :15] = (listener[..., :15] > 0.7)
    speaker = rng.random((N, T, 25)).astype(np.float32)
    neighbours = np.eye(N, dtype=np.int64)
    neighbours[np.arange(N), (np.arange(N) + 1) % N] = 1
    return listener, speaker, neighbours


def test_mean_fr_values_follow_from_a_constant_prediction(problem):
    listener, speaker, s = problem
    mean = react_baselines.mean_sequence([listener[k] for k in range(N)], T)
    pred = react_baselines.mean_fr(mean, N)
    assert pred.shape == (N, 10, T, 25)
    np.testing.assert_allclose(pred[0, 0, 0], listener.astype(np.float64).mean(axis=(0, 1)), rtol=1e-6)
    m = suite.score(pred, listener, speaker, s)
    assert m["FRCorr"] == 0 and m["FRDiv"] == 0 and m["FRVar"] == 0 and m["FRDvs"] == 0
    assert m["FRSyn"] == 49


def test_random_diversity_is_that_of_uniform_noise(problem):
    listener, speaker, s = problem
    pred = react_baselines.random(N, T, seed=0)
    assert pred.shape == (N, 10, T, 25) and pred.min() >= 0 and pred.max() < 1
    np.testing.assert_array_equal(pred, react_baselines.random(N, T, seed=0))
    m = suite.score(pred, listener, speaker, s)
    # E|x - y|^2 = 1/6 for independent U[0,1); variance 1/12; 6*10*120*25 values
    assert m["FRDiv"] == pytest.approx(1 / 6, abs=3e-3)
    assert m["FRVar"] == pytest.approx(1 / 12, abs=2e-3)
    assert m["FRDvs"] == pytest.approx(1 / 6, abs=3e-3)


def test_gt_and_mime_repeat_one_clip(problem):
    listener, speaker, s = problem
    g = suite.score(react_baselines.gt(listener), listener, speaker, s)
    assert g["FRDist"] == 0 and g["FRDiv"] == 0
    assert g["FRVar"] == pytest.approx(listener.astype(np.float64).var(axis=1, ddof=1).mean())
    mime = react_baselines.mime(speaker)
    np.testing.assert_array_equal(mime[:, 7], speaker)
    assert suite.score(mime, listener, speaker, s)["FRDiv"] == 0


def test_mean_seq_is_the_per_frame_train_mean():
    train = [np.full((5, 25), 1.0), np.full((6, 25), 3.0)]
    mean = react_baselines.mean_sequence(train, 5)
    np.testing.assert_array_equal(mean, np.full((5, 25), 2.0))
    pred = react_baselines.mean_seq(mean, 2, reactions=3)
    assert pred.shape == (2, 3, 5, 25) and (pred == 2.0).all()
    with pytest.raises(InputError, match="1 are shorter"):
        react_baselines.mean_sequence(train, 6)
    with pytest.raises(InputError, match="unknown REACT baseline"):
        react_baselines.predictions("meanfr", "x", "val")


def test_baseline_cli_and_score_oracle_flag(tmp_path):
    """baselines.react writes the mirrored (N, 10, 750, 25) array; `score --oracle` records the GT row as an
    oracle (never ranked) and a baseline without the flag is not one."""
    import json

    from click.testing import CliRunner

    from dyadbench.cli import cli
    from dyadbench.synth.react_writer import write_react_split

    root = tmp_path / "react"
    for split in ("train", "val"):
        write_react_split(root, split=split, clips=2, progress=False)
    runner = CliRunner()
    for name, flags in (("gt", ["--oracle"]), ("mean-seq", [])):
        out = tmp_path / f"{name}.npz"
        result = runner.invoke(react_baselines.main, [name, "--data", str(root), "--split", "val", "--out", str(out)])
        assert result.exit_code == 0, result.output
        with np.load(out) as z:
            assert z["predictions"].shape == (4, 10, 750, 25)
        result = runner.invoke(cli, ["score", str(out), "--suite", "react", "--gt", str(root), "--split", "val",
                                     "--model", name, "--out", str(tmp_path / name), *flags])
        assert result.exit_code == 0, result.output
        record = json.loads((tmp_path / name / "result.json").read_text())
        assert record["model"]["oracle"] is (name == "gt") and record["model"]["name"] == name
        if name == "gt":
            assert record["metrics"]["FRDist"] == 0.0
