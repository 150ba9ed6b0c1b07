"""Loading the released TIMAR checkpoint: refusals (each naming the file) and the command line end to end."""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import pytest
import torch

from dyadbench.errors import InputError
from dyadbench.protocol.interface import ModelOptions
from dyadbench.torch_files import load_tensors_only
from models.timar import official
from models.timar.registry import build_timar, shipped
from tests.hostile_cli import run_cli
from tests.timar_official_fixture import (CHECKPOINT, FIXTURE, HEADS, WAV2VEC, arrays,
                                          write_dualtalk_split)

DUALTALK_CHECKPOINT = FIXTURE.parent / "dualtalk_b" / "checkpoint.pth"


class Payload:
    """A pickled object the format does not allow (its class is a global outside the allow-list)."""


class RunsCommand:
    """Unpickling this would run a shell command."""

    def __init__(self, marker: Path):
        self.marker = marker

    def __reduce__(self):
        return os.system, (f"touch {self.marker}",)


def released_payload() -> dict:
    return load_tensors_only(CHECKPOINT, allowed_globals=official.official_globals())


def refused(path: Path, match: str) -> str:
    with pytest.raises(InputError, match=match) as info:
        official.load_official(path, heads=HEADS)
    assert str(path) in str(info.value)
    return str(info.value)


def test_a_pickled_command_is_refused_and_never_run(tmp_path):
    marker, path = tmp_path / "ran", tmp_path / "evil.pth"
    torch.save({**released_payload(), "args": RunsCommand(marker)}, path)
    refused(path, r"refused to load.*system")
    assert not marker.exists()


def test_a_custom_class_is_refused(tmp_path):
    path = tmp_path / "custom.pth"
    torch.save({**released_payload(), "scaler": Payload()}, path)
    refused(path, r"refused to load.*Payload")


def test_a_truncated_file_is_refused(tmp_path):
    path = tmp_path / "truncated.pth"
    path.write_bytes(CHECKPOINT.read_bytes()[:400_000])
    refused(path, "truncated or not a torch.save file")


@pytest.mark.parametrize("other", [DUALTALK_CHECKPOINT, shipped("timar-stream")])
def test_a_file_of_another_model_is_refused(other):
    refused(other, "not an official TIMAR checkpoint")


def test_missing_and_unexpected_keys_are_listed(tmp_path):
    payload = released_payload()
    ema = dict(payload["model_ema"])
    del ema["diffusion_pos_embed_learned"]
    ema["diffloss.net.res_blocks.9.in_ln.weight"] = torch.zeros(40)
    ema["decoder_embed.weight"] = torch.zeros(2, 2)
    path = tmp_path / "keys.pth"
    torch.save({**payload, "model_ema": ema}, path)
    message = refused(path, "missing keys: diffusion_pos_embed_learned")
    assert "unexpected keys: decoder_embed.weight, diffloss.net.res_blocks.9.in_ln.weight" in message


def test_the_timar_factory_refuses_other_models_files_naming_them():
    with pytest.raises(InputError, match="not a dyadbench checkpoint") as info:
        build_timar(ModelOptions(weights=DUALTALK_CHECKPOINT))
    assert str(DUALTALK_CHECKPOINT) in str(info.value)
    with pytest.raises(InputError, match="use --model timar"):
        from models.timar.registry import build_timar_stream  # noqa: PLC0415

        build_timar_stream(ModelOptions(weights=CHECKPOINT))


def eval_args(data: Path, weights: Path, out: Path) -> list:
    return ["eval", "--model", "timar", "--weights", weights, "--wav2vec", WAV2VEC, "--speech-norm", "clip",
            "--data", data, "--split", "test", "--out", out, "--threads", "1"]


def test_eval_runs_the_released_file_and_its_native_conversion_identically(tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("DYADBENCH_CACHE", str(tmp_path / "cache"))
    monkeypatch.setitem(official.FACTORY_HEADS, "timar_tiny_b", HEADS)  # the fixture's factory: 3 heads
    data = tmp_path / "data"
    write_dualtalk_split(arrays()[0], data / "test")
    native = tmp_path / "timar-native.pt"
    code, out, err = run_cli(capsys, "weights", "convert", CHECKPOINT, "--wav2vec", WAV2VEC, "--out", native)
    assert code == 0, err
    results = {}
    for name, weights in (("official", CHECKPOINT), ("native", native)):
        code, out, err = run_cli(capsys, *eval_args(data, weights, tmp_path / name))
        assert code == 0, err
        results[name] = json.loads((tmp_path / name / "result.json").read_text())
    for stem in ("fixture_speaker1", "fixture_speaker2"):
        np.testing.assert_array_equal(np.load(tmp_path / "official" / "predictions" / f"{stem}.npy"),
                                      np.load(tmp_path / "native" / "predictions" / f"{stem}.npy"))
    first, second = results["official"], results["native"]
    assert first["model"]["config"]["format"] == "official" and second["model"]["config"]["format"] == "native"
    released_digest = first["model"]["weights_digest"]
    assert second["model"]["config"]["converted_from"]["digest"] == released_digest != second["model"]["weights_digest"]
    assert first["protocol"]["speech_norm"] == "clip" and first["configuration"]["speech_norm"] == "clip"
    assert any("not strictly causal" in note for note in first["notes"])


def test_convert_needs_heads_for_an_unknown_factory(tmp_path, capsys):
    code, _, err = run_cli(capsys, "weights", "convert", CHECKPOINT, "--out", tmp_path / "x.pt")
    assert code == 2 and err.startswith("error: ") and "--heads N" in err and "Traceback" not in err
    code, _, err = run_cli(capsys, "weights", "convert", CHECKPOINT, "--heads", "3", "--out", tmp_path / "x.pt")
    assert code == 0 and (tmp_path / "x.pt").is_file()
