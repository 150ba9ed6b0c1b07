"""The command line starts, explains itself, and runs as ``python -m dyadbench``."""

import subprocess
import sys

from click.testing import CliRunner

from dyadbench.cli import COMMANDS, cli


def test_help_lists_every_command():
    result = CliRunner().invoke(cli, ["--help"])
    assert result.exit_code == 0
    for name in COMMANDS:
        assert name in result.output


def test_every_command_has_help():
    runner = CliRunner()
    for name in COMMANDS:
        result = runner.invoke(cli, [name, "--help"])
        assert result.exit_code == 0, (name, result.output)
        assert "Usage" in result.output


def test_python_dash_m():
    proc = subprocess.run([sys.executable, "-m", "dyadbench", "--version"], capture_output=True, text=True)
    assert proc.returncode == 0
    assert "dyadbench" in proc.stdout
