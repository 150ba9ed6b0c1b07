"""The command a checkpoint records is the one typed, also when the CLI runs from Python (click's test runner,
``main([...])``), where ``sys.argv`` is the calling program's."""

from __future__ import annotations

import click
from click.testing import CliRunner

from dyadbench.cli.invocation import recorded_command
from dyadbench.cli.lazy import lazy_group


@click.command()
@click.option("--name", default="x")
@click.argument("rest", nargs=-1)
def probe(name, rest):
    click.echo(repr(recorded_command()))


@click.group(cls=lazy_group({"probe": ("tests.test_invocation:probe", "echo the recorded command")}))
def root():
    pass


def test_the_root_group_records_the_arguments_as_typed():
    result = CliRunner().invoke(root, ["probe", "--name", "a b", "it's"])
    assert result.exit_code == 0, result.output
    assert result.output.strip() == repr("dyadbench probe --name 'a b' 'it'\"'\"'s'")


def test_a_sub_command_called_without_the_root_records_nothing():
    result = CliRunner().invoke(probe, ["--name", "z"])
    assert result.exit_code == 0 and result.output.strip() == "None"
    assert recorded_command() is None  # outside any click context
