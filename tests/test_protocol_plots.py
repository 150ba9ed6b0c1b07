"""``dyadbench plot``: trajectory and context-curve PNGs."""

from __future__ import annotations

import numpy as np
import pytest
from click.testing import CliRunner

from dyadbench.cli import cli
from dyadbench.errors import ConfigError
from dyadbench.motion import FLAME56
from dyadbench.plotting import parse_dims, plot_trajectories
from dyadbench.synth.writers import write_dualtalk_split
from tests.protocol_clips import isolated_cache  # noqa: F401

PNG = b"\x89PNG\r\n\x1a\n"


def test_trajectories_and_context_curves_from_an_eval(tmp_path):
    data = tmp_path / "dt"
    for split in ("train", "test"):
        write_dualtalk_split(data, split=split, clips=1, seed=0, progress=False)
    runner = CliRunner()
    for n in (0, 3):
        result = runner.invoke(cli, ["eval", "--model", "lagged-mirror", "--data", str(data), "--context", str(n),
                                     "--out", str(tmp_path / f"n{n}")], catch_exceptions=False)
        assert result.exit_code == 0, result.output
    result = runner.invoke(cli, ["plot", "trajectories", str(tmp_path / "n0" / "predictions"), "--clip",
                                 "synth_test_00000", "--agent", "speaker2", "--data", str(data),
                                 "--dims", "exp:0,jaw:0,pose:2", "--out", str(tmp_path / "t.png")],
                           catch_exceptions=False)
    assert result.exit_code == 0, result.output
    assert (tmp_path / "t.png").read_bytes().startswith(PNG)
    result = runner.invoke(cli, ["plot", "context", str(tmp_path / "n0"), str(tmp_path / "n3"), "--metric", "fd_exp",
                                 "--metric", "rpcc_jaw", "--out", str(tmp_path / "c.png")], catch_exceptions=False)
    assert result.exit_code == 0, result.output
    assert (tmp_path / "c.png").read_bytes().startswith(PNG)
    result = runner.invoke(cli, ["plot", "context", str(tmp_path / "n0"), "--metric", "nope",
                                 "--out", str(tmp_path / "x.png")])
    assert result.exit_code != 0 and "nope" in str(result.exception)


def test_dims_are_checked():
    assert parse_dims("exp:3, pose:0", FLAME56) == (("exp", 3), ("pose", 0))
    for bad, match in (("lips:0", "unknown component"), ("jaw:3", "out of range"), ("exp", "component:index"),
                       ("", "selected nothing")):
        with pytest.raises(ConfigError, match=match):
            parse_dims(bad, FLAME56)


def test_trajectory_shapes_are_checked(tmp_path):
    with pytest.raises(ConfigError, match="prediction must be"):
        plot_trajectories(np.zeros((10, 7)), np.zeros((10, 56)), None, "flame56", tmp_path / "x.png")
