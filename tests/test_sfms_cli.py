"""SFMS trainers end to end on a few generated clips: tokenizer → predictor → factory → protocol."""

import json

import numpy as np
import pytest
from click.testing import CliRunner

from dyadbench.errors import ConfigError
from dyadbench.protocol.config import ProtocolConfig
from dyadbench.protocol.interface import ModelOptions
from dyadbench.protocol.streaming import stream_agent
from dyadbench.synth.corpus import make_clips
from dyadbench.training.checkpoint import file_digest, load_checkpoint
from models.sfms import cli
from models.sfms.registry import build_sfms

SMALL = ["--set", "width=32", "--set", "heads=2", "--set", "ffn=64", "--steps", "3", "--batch", "4",
         "--val-windows", "8", "--threads", "1"]


@pytest.fixture
def tiny_data(monkeypatch):
    train, val = make_clips("train", 2, duration_s=6.0), make_clips("val", 1, duration_s=6.0)
    monkeypatch.setattr(cli, "load_split_clips", lambda *a, **k: (train, val, {"dataset": "generated"}))
    return val


def test_trainers_write_checkpoints_that_stream(tmp_path, tiny_data):
    runner = CliRunner()
    tok = tmp_path / "tok.pt"
    res = runner.invoke(cli.train_tokenizer, SMALL + ["--set", "pe_dim=8", "--keyframes", "5", "--out", str(tok)])
    assert res.exit_code == 0, res.output
    payload = load_checkpoint(tok, expect_model="sfms-tokenizer")
    assert payload["config"]["tokenizer"]["keyframes"] == 5 and payload["config"]["tokenizer"]["width"] == 32
    assert payload["meta"]["seed"] == 0 and tok.with_suffix(".history.json").is_file()
    full = tmp_path / "sfms.pt"
    res = runner.invoke(cli.train_predictor, SMALL + ["--set", "audio_bins=8", "--tokenizer", str(tok),
                                                     "--out", str(full)])
    assert res.exit_code == 0, res.output
    assert load_checkpoint(full, expect_model="sfms")["meta"]["tokenizer_sha256"] == file_digest(tok)
    history = json.loads(full.with_suffix(".history.json").read_text())
    assert len(history["steps"]) == 3 and "unigram_ce" in history["val"][-1]
    model = build_sfms(ModelOptions(weights=full))
    assert model.info.config["tokenizer"]["keyframes"] == 5
    out = stream_agent(model, tiny_data[0], "speaker1", ProtocolConfig(context=1)).motion
    assert out.shape == (150, 56) and np.isfinite(out).all()


def test_overrides_parse_json_values_and_reject_bad_pairs():
    assert cli.parse_overrides(("keyframes=10", "fsq_levels=[8,5,5,5]", "quantizer=vq", "keyframe_cap=null")) == {
        "keyframes": 10, "fsq_levels": (8, 5, 5, 5), "quantizer": "vq", "keyframe_cap": None}
    with pytest.raises(ConfigError, match="FIELD=VALUE"):
        cli.parse_overrides(("keyframes",))


def test_unknown_field_or_choice_is_a_config_error(tmp_path, tiny_data):
    res = CliRunner().invoke(cli.train_tokenizer, ["--set", "mask_sharing=pixel", "--out", str(tmp_path / "x.pt")])
    assert isinstance(res.exception, ConfigError) and "mask_sharing" in str(res.exception)


@pytest.mark.parametrize("pair, field", [("fsq_levels=8,5,5,5", "fsq_levels"), ("keyframes=6.5", "keyframes"),
                                         ("suppression_radius=two", "suppression_radius")])
def test_a_value_of_the_wrong_kind_is_a_config_error_naming_the_field(tmp_path, pair, field):
    res = CliRunner().invoke(cli.train_tokenizer, ["--set", pair, "--out", str(tmp_path / "x.pt")])
    assert isinstance(res.exception, ConfigError) and f"TokenizerConfig.{field} = " in str(res.exception)
    assert not (tmp_path / "x.pt").exists()
