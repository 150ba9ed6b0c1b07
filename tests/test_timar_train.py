"""TIMAR training: checkpoints round-trip, bit-exact resume, the torch.distributed path, the CLI."""

from __future__ import annotations

import socket
from dataclasses import replace
from pathlib import Path

import pytest
import torch
import torch.distributed as dist
from click.testing import CliRunner

from dyadbench.cli.train import train
from dyadbench.errors import InputError
from dyadbench.protocol.interface import ModelOptions
from dyadbench.training.checkpoint import load_checkpoint
from models.timar.config import preset
from models.timar.data import data_digest
from models.timar.registry import build_timar, build_timar_stream
from models.timar.train import TrainSettings, train_timar_model
from protocol_clips import make_source
from test_timar_model import MICRO

SETTINGS = TrainSettings(epochs=1, batch_size=4, seed=3, stride_turns=2)


@pytest.fixture(scope="module")
def source():
    return make_source(2, seconds=2.0, split="train")  # 10 turns of 0.2 s per clip -> 8 windows


def run(tmp: Path, source, variant: str = "faithful", **changes) -> Path:
    return train_timar_model(preset("tiny", variant, **MICRO), source, tmp, replace(SETTINGS, **changes),
                             progress=False)


def test_checkpoint_round_trip_through_the_factory(tmp_path, source):
    path = run(tmp_path, source)
    state = load_checkpoint(path, expect_model="timar")
    assert state["meta"]["data_digest"] == data_digest(source)
    assert state["meta"]["seed"] == 3 and state["meta"]["epoch"] == 1 and state["config"]["dim"] == 16
    model = build_timar(ModelOptions(weights=path)).model
    for key, value in model.state_dict().items():
        assert torch.equal(value, state["model"][key]), key


def test_export_writes_weights_only_and_cannot_resume(tmp_path, source):
    exported = tmp_path / "w.pt"
    train_timar_model(preset("tiny", "stream", **MICRO), source, tmp_path / "run", SETTINGS, export=exported,
                      progress=False)
    state = load_checkpoint(exported, expect_model="timar-stream")
    assert "train_state" not in state
    assert build_timar_stream(ModelOptions(weights=exported)).model.cfg.variant == "stream"
    with pytest.raises(InputError, match="no training state"):
        train_timar_model(preset("tiny", "stream", **MICRO), source, tmp_path / "again",
                          replace(SETTINGS, epochs=2), resume=exported, progress=False)


@pytest.mark.parametrize("variant", ["faithful", "stream"])
def test_resume_continues_bit_exactly(tmp_path, source, variant):
    straight = load_checkpoint(run(tmp_path / "a", source, variant, epochs=2))
    first = run(tmp_path / "b", source, variant, epochs=1)
    resumed = load_checkpoint(train_timar_model(preset("tiny", variant, **MICRO), source, tmp_path / "c",
                                                replace(SETTINGS, epochs=2), resume=first, progress=False))
    def losses(state: dict) -> list[tuple]:
        return [(h["epoch"], h["steps"], h["loss"]) for h in state["meta"]["history"]]

    assert losses(resumed) == losses(straight)
    for key, value in straight["model"].items():  # EMA weights
        assert torch.equal(value, resumed["model"][key]), key
    for key, value in straight["train_state"]["model"].items():
        assert torch.equal(value, resumed["train_state"]["model"][key]), key


def test_resume_refuses_other_data(tmp_path, source):
    first = run(tmp_path / "a", source)
    other = make_source(2, seconds=2.0, seed=9, split="train")
    with pytest.raises(InputError, match="data digest differs"):
        train_timar_model(preset("tiny", **MICRO), other, tmp_path / "b", replace(SETTINGS, epochs=2),
                          resume=first, progress=False)


def test_training_reduces_the_loss_over_epochs(tmp_path, source):
    history = load_checkpoint(run(tmp_path, source, epochs=4, lr=3e-3))["meta"]["history"]
    assert history[-1]["loss"] < history[0]["loss"]


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_torchrun_environment_initialises_gloo_and_trains(tmp_path, source, monkeypatch):
    # what torchrun sets for a single process; multi-process runs are not exercised here
    for key, value in {"RANK": "0", "WORLD_SIZE": "1", "LOCAL_RANK": "0", "MASTER_ADDR": "127.0.0.1",
                       "MASTER_PORT": str(_free_port())}.items():
        monkeypatch.setenv(key, value)
    try:
        path = run(tmp_path, source)
        assert dist.is_initialized() and dist.get_backend() == "gloo"
        assert load_checkpoint(path)["meta"]["world_size"] == 1
    finally:
        if dist.is_initialized():
            dist.destroy_process_group()


def test_cli_help_lists_every_option():
    result = CliRunner().invoke(train, ["timar", "--help"])
    assert result.exit_code == 0
    for option in ("--config", "--data", "--epochs", "--resume", "--export", "--run-dir", "--seed", "--clips"):
        assert option in result.output


@pytest.mark.parametrize("trainer", ["timar", "timar-stream", "dualtalk"])
@pytest.mark.parametrize("args, expected", [([], ("synthetic-v2", None)),
                                            (["--dataset", "synthetic"], ("synthetic", None))])
def test_train_reads_the_train_split_of_the_named_embedded_corpus(tmp_path, monkeypatch, trainer, args, expected):
    """`dyadbench train <model> --dataset synthetic` trains on corpus v1's train split; without --dataset the
    embedded default. (The split opener is replaced so no corpus is generated; it stops the command.)"""
    import dyadbench.protocol.runner as runner
    from dyadbench.cli import main

    opened = []

    def fake_open(name, root, split):
        opened.append((name, root, split))
        raise InputError(name, "stop here")

    monkeypatch.setattr(runner, "open_dataset_split", fake_open)
    with pytest.raises(SystemExit) as exc:
        main(["train", trainer, *args, "--out", str(tmp_path / "run")])
    assert exc.value.code == 2 and opened == [(*expected, "train")]
