"""Every trainer with ``--device`` refuses a device it cannot train on, naming the option, before any work."""

from __future__ import annotations

import pytest
import torch
from click.testing import CliRunner

from dyadbench.cli import cli

TRAINERS = (["stygazetalk-style", "--config", "tiny-se64"], ["stygazetalk", "--config", "tiny-base"],
            ["sfms-tokenizer", "--config", "tiny"], ["sfms", "--config", "tiny", "--tokenizer", __file__])
BAD = [("meta", "models run on cpu or cuda"), ("gpu7", "is not a torch device")]
if not torch.cuda.is_available():
    BAD.append(("cuda", "CUDA is not available here"))


@pytest.mark.parametrize("trainer", TRAINERS, ids=lambda t: t[0])
@pytest.mark.parametrize("device, message", BAD)
def test_a_device_the_trainer_cannot_use_is_refused(tmp_path, trainer, device, message):
    out = tmp_path / "x.pt"
    result = CliRunner().invoke(cli, ["train", *trainer, "--device", device, "--export", str(out)])
    assert result.exit_code == 2, result.output
    assert message in result.output and "--device" in result.output
    assert not out.exists()
