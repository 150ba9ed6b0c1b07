"""``dyadbench data synth | validate | info`` end to end."""

import json
from pathlib import Path

import pytest
from click.testing import CliRunner

from dyadbench.cli import cli

DEMO = Path("/work/shared/data/dualtalk-demo")


def run(*args):
    return CliRunner().invoke(cli, list(map(str, args)))


def test_synth_validate_info(tmp_path):
    result = run("data", "synth", "--out", tmp_path, "--split", "ood", "--clips", 2, "--seed", 3)
    assert result.exit_code == 0, result.output
    summary = json.loads(result.output[result.output.index("{"):])
    assert summary["clips"] == 2 and summary["seed"] == 3 and summary["split"] == "ood"
    assert len(list((tmp_path / "ood").glob("*_speaker?.npz"))) == 4

    result = run("data", "validate", tmp_path / "ood")
    assert result.exit_code == 0 and "0 errors" in result.output and "OK" in result.output

    result = run("data", "info", tmp_path)
    info = json.loads(result.output[result.output.index("{"):])
    split = info["splits"]["ood"]
    assert split["dialogues"] == 2 and split["frames"] > 0 and split["turns"]["total"] >= 2
    assert split["hours"] == pytest.approx(split["frames"] / 25 / 3600)


def test_validate_fails_naming_the_file(tmp_path):
    assert run("data", "synth", "--out", tmp_path, "--clips", 1).exit_code == 0
    broken = next((tmp_path / "test").glob("*_speaker2.wav"))
    broken.write_bytes(broken.read_bytes()[:1000])
    result = run("data", "validate", tmp_path / "test")
    assert result.exit_code == 1
    assert str(broken) in result.output and "truncated" in result.output


@pytest.mark.skipif(not DEMO.is_dir(), reason="real DualTalk demo clips not on this machine")
def test_validate_real_demo_reports_exactly_the_missing_npz():
    result = run("data", "validate", DEMO)
    assert result.exit_code == 1
    errors = [line for line in result.output.splitlines() if line.startswith("error:")]
    assert len(errors) == 2
    assert "UbjUDM1MiGE_sub_video_72_speaker1.npz" in errors[0] + errors[1]
    assert "xkHwlcDSOjc_sub_video_109_000_speaker2.npz" in errors[0] + errors[1]


def test_unknown_split_is_a_clear_error(tmp_path):
    result = CliRunner().invoke(cli, ["data", "synth", "--out", str(tmp_path), "--split", "dev"],
                                standalone_mode=False)
    assert "unknown synthetic split 'dev'" in str(result.exception)
