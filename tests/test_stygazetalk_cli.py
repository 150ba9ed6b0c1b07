"""The StyGazeTalk trainers and `dyadbench eval --style-from` end to end on a tiny gaze-head root."""

from __future__ import annotations

import json

import numpy as np
import pytest
from click.testing import CliRunner

from dyadbench.cli import cli
from dyadbench.synth.gaze_writer import write_gaze_split
from models.stygazetalk.checkpoints import load_style_model, load_system

pytestmark = pytest.mark.slow  # trains twice and runs two evals (~30 s on an idle 2-core machine)


@pytest.fixture(scope="module")
def root(tmp_path_factory):
    root = tmp_path_factory.mktemp("gaze")
    for split, n in (("train", 8), ("val", 8), ("test", 2)):
        write_gaze_split(root, split=split, clips=n, seed=0, duration_s=24.0 if split != "test" else 8.0)
    return root


def _invoke(args):
    result = CliRunner().invoke(cli, args, catch_exceptions=False)
    assert result.exit_code == 0, result.output
    return result.output


def test_trainers_and_eval_with_style_transfer(root, tmp_path):
    se = tmp_path / "se.pt"
    out = _invoke(["train", "stygazetalk-style", "--config", "tiny-se64", "--dataset", "gaze", "--data", str(root),
                   "--steps", "2", "--batch", "8", "--val-every", "1", "--threads", "1", "--out", str(se)])
    assert "retrieval top-1" in out
    style, meta = load_style_model(se)
    assert meta["steps"] == 2 and meta["seed"] == 0 and 0.0 <= meta["val_retrieval_top1"] <= 1.0
    assert meta["settings"] == {"device": "cpu", "threads": 1}  # how it was trained is recorded
    assert meta["command"].startswith("dyadbench train stygazetalk-style --config tiny-se64")

    gen = tmp_path / "gen.pt"
    out = _invoke(["train", "stygazetalk", "--config", "tiny-se64", "--style-encoder", str(se), "--dataset", "gaze",
                   "--data", str(root), "--steps", "2", "--batch", "4", "--rollout-prob", "0.5", "--threads", "1",
                   "--out", str(gen)])
    assert "val loss" in out
    system, gmeta = load_system(gen)
    assert system.cfg.rollout_prob == 0.5  # the D9 override is recorded in the checkpoint
    assert gmeta["steps"] == 2 and len(gmeta["style_encoder_digest"]) == 64
    assert np.array_equal(system.motion_norm.mean.numpy(), style.motion_norm.mean.numpy())
    assert system.residual_pool.abs().sum() > 0

    runs = {}
    for tag, extra in (("own", []), ("transfer", ["--style-from", "test001_spk2"])):
        runs[tag] = tmp_path / tag
        _invoke(["eval", "--model", "stygazetalk", "--dataset", "gaze", "--data", str(root), "--split", "test",
                 "--context", "2", "--weights", str(gen), "--out", str(runs[tag])] + extra)
    own = np.load(runs["own"] / "predictions" / "test000_spk1_subject.npy")
    moved = np.load(runs["transfer"] / "predictions" / "test000_spk1_subject.npy")
    assert own.shape == moved.shape == (200, 7)
    assert np.array_equal(own[:50], moved[:50]) and not np.array_equal(own[50:], moved[50:])
    result = json.loads((runs["transfer"] / "result.json").read_text())
    assert result["model"]["config"]["style_from"].startswith("array")


def test_style_variant_without_style_encoder_is_a_clear_error(root, tmp_path):
    result = CliRunner().invoke(cli, ["train", "stygazetalk", "--config", "tiny-se32", "--dataset", "gaze",
                                      "--data", str(root), "--out", str(tmp_path / "g.pt")])
    assert result.exit_code != 0 and "--style-encoder" in str(result.exception) + result.output
