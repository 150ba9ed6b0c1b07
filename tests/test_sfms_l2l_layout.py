"""SFMS on the Learning2Listen layout: the shipped mel rows reach the predictor through the protocol.

The L2L layout ships the speaker's mel spectrogram (4 rows × 128 bins per frame), no waveform. These
tests train, stream and score SFMS on a split dyadbench writes in that layout.
"""

import json
from pathlib import Path

import pytest
import torch
from click.testing import CliRunner

from dyadbench.cli import cli
from dyadbench.datasets import l2l
from dyadbench.errors import InputError
from dyadbench.metrics.l2l import L2LParams
from dyadbench.protocol.causality import check_causal
from dyadbench.protocol.config import ProtocolConfig
from dyadbench.protocol.interface import ModelOptions
from dyadbench.protocol.streaming import stream_agent
from dyadbench.scoring import l2l as l2l_scoring
from dyadbench.training.checkpoint import load_checkpoint, save_checkpoint
import models.sfms.checkpoints
from models.sfms.bundle import PREDICTOR_MODEL, SFMS
from models.sfms.config import predictor_preset, tokenizer_preset
from models.sfms.predictor import SFMSPredictor
from models.sfms.registry import build_sfms
from models.sfms.tokenizer import SFMSTokenizer
from tests.l2l_root import l2l_train_test  # noqa: F401

torch.set_num_threads(1)
SHIPPED_L2L = Path(models.sfms.checkpoints.__file__).parent / "sfms-tiny-l2l.pt"
SMALL = ["--set", "width=32", "--set", "heads=2", "--set", "ffn=64", "--steps", "3", "--batch", "4",
         "--val-windows", "8", "--threads", "1"]


@pytest.fixture(scope="module")
def root(l2l_train_test):
    return l2l_train_test


def _weights(path, bins: int):
    torch.manual_seed(0)
    tok = SFMSTokenizer(tokenizer_preset("tiny", width=32, heads=2, ffn=64, pe_dim=8))
    pred = SFMSPredictor(predictor_preset("tiny", width=32, heads=2, ffn=64, audio_bins=bins), 56, tok.cfg.n_classes)
    model = SFMS(tok, pred).eval()
    save_checkpoint(path, model_state=model.state_dict(), config=model.config(), meta={"model": PREDICTOR_MODEL})
    return path


@pytest.fixture(scope="module")
def weights(tmp_path_factory):
    return _weights(tmp_path_factory.mktemp("w") / "sfms-mel128.pt", 128)


@pytest.fixture(scope="module")
def clip(root):
    return l2l.open_split(root, "test").load("synth_test_00000")


def test_causal_on_a_listening_window(weights, clip):
    check_causal(lambda: build_sfms(ModelOptions(weights=weights)), clip, "listener", ProtocolConfig(context=1), 0)


def test_the_shipped_mel_rows_are_what_the_predictor_hears(weights, clip, monkeypatch):
    """The first step of turn 1 (frames [30, 38), 40 past frames) reads exactly the mel rows of frames 0..37."""
    heard = []
    forward = SFMSPredictor.forward

    def recording(self, past, speaker, audio, valid):
        heard.append((audio.clone(), valid.clone()))
        return forward(self, past, speaker, audio, valid)

    monkeypatch.setattr(SFMSPredictor, "forward", recording)
    stream_agent(build_sfms(ModelOptions(weights=weights)), clip, "listener", ProtocolConfig(context=1))
    audio, valid = heard[4]  # turn 0 takes steps at frames 0, 8, 16, 24
    mel = torch.as_tensor(clip.participant("speaker").speech_features)  # the weights' audio stats are 0 / 1
    assert valid[0].tolist() == [False] * 10 + [True] * 38
    torch.testing.assert_close(audio[0, 40:], mel[:152], rtol=0, atol=0)
    assert not audio[0, :40].any()


def test_a_predictor_of_other_mel_bins_is_refused_with_the_fix(tmp_path, clip):
    model = build_sfms(ModelOptions(weights=_weights(tmp_path / "mel32.pt", 32)))
    with pytest.raises(InputError, match=r"128 bins × 4 rows per frame.*--set audio_bins=128") as err:
        stream_agent(model, clip, "listener", ProtocolConfig())
    assert "synth_test_00000_speaker" in str(err.value)


def test_train_eval_and_score_on_the_l2l_layout(root, tmp_path):
    runner = CliRunner()
    tok, full = tmp_path / "tok.pt", tmp_path / "sfms.pt"
    data = ["--dataset", "l2l", "--root", str(root)]
    res = runner.invoke(cli, ["train", "sfms-tokenizer", *SMALL, "--set", "pe_dim=8", *data, "--out", str(tok)])
    assert res.exit_code == 0, res.output
    res = runner.invoke(cli, ["train", "sfms", *SMALL, *data, "--tokenizer", str(tok), "--out", str(full)])
    assert res.exit_code != 0 and "--set audio_bins=128" in str(res.exception or res.output)
    res = runner.invoke(cli, ["train", "sfms", *SMALL, "--set", "audio_bins=128", *data, "--tokenizer", str(tok),
                              "--out", str(full)])
    assert res.exit_code == 0, res.output
    payload = load_checkpoint(full, expect_model="sfms")
    assert payload["config"]["predictor"]["audio_bins"] == 128 and payload["meta"]["data"]["dataset"] == "l2l"

    run = tmp_path / "run"
    res = runner.invoke(cli, ["eval", "--model", "sfms", "--weights", str(full), "--dataset", "l2l", "--data",
                              str(root), "--split", "test", "--context", "1", "--out", str(run)])
    assert res.exit_code == 0, res.output
    result = json.loads((run / "result.json").read_text())
    stems = sorted(p.stem for p in (run / "predictions").glob("*.npy"))
    assert result["suite"] == "l2l" and stems == l2l.ground_truth(root, "test")[0]  # listeners only
    res = runner.invoke(cli, ["score", str(run / "predictions"), "--suite", "l2l", "--gt", str(root),
                              "--out", str(tmp_path / "scored")])
    assert res.exit_code == 0, res.output
    rescored = json.loads((tmp_path / "scored" / "result.json").read_text())
    assert rescored["metrics"] == result["metrics"]
    res = runner.invoke(cli, ["leaderboard", str(run), "--out", str(tmp_path / "lb")])
    assert res.exit_code == 0, res.output
    header = (tmp_path / "lb" / "l2l_wide.csv").read_text().splitlines()[0].split(",")
    # the wide table's columns: the suite's ranked ones (ground-truth references are a row, not columns)
    assert header[header.index("items") + 1:] == [c.key for c in l2l_scoring.columns(L2LParams()) if c.table]


def test_shipped_l2l_checkpoint_reads_l2l_mels_and_records_its_training(clip):
    model = build_sfms(ModelOptions(weights=SHIPPED_L2L))
    meta = model.info.config["train_meta"]
    assert model.info.config["predictor"]["audio_bins"] == 128 and meta["data"]["dataset"] == "l2l"
    assert meta["best_val_ce"] < meta["val"][-1]["unigram_ce"]  # beats the class-frequency predictor
    out = stream_agent(model, clip, "listener", ProtocolConfig(context=1)).motion
    assert out.shape == (60, 56) and torch.isfinite(torch.as_tensor(out)).all()
