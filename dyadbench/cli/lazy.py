"""A click group whose sub-commands are imported only when invoked (fast ``--help``, no torch import)."""

from __future__ import annotations

import importlib

import click

from dyadbench.cli.invocation import ARGV_KEY


class LazyGroup(click.Group):
    """Sub-commands come from ``commands_table``: name -> ("module:attribute", one-line help)."""

    commands_table: dict[str, tuple[str, str]] = {}
    section: str = "Commands"

    def list_commands(self, ctx: click.Context) -> list[str]:
        return list(self.commands_table)

    def get_command(self, ctx: click.Context, cmd_name: str) -> click.Command | None:
        if cmd_name not in self.commands_table:
            return None
        module_name, _, attr = self.commands_table[cmd_name][0].partition(":")
        return getattr(importlib.import_module(module_name), attr)

    def make_context(self, info_name: str | None, args: list[str], parent: click.Context | None = None,
                     **extra) -> click.Context:
        """The root group's context also keeps the arguments it was given (:mod:`dyadbench.cli.invocation`)."""
        argv = list(args)
        ctx = super().make_context(info_name, args, parent=parent, **extra)
        if parent is None:
            ctx.meta[ARGV_KEY] = argv
        return ctx

    def format_commands(self, ctx: click.Context, formatter: click.HelpFormatter) -> None:
        with formatter.section(self.section):
            formatter.write_dl([(name, help_text) for name, (_, help_text) in self.commands_table.items()])


def lazy_group(commands: dict[str, tuple[str, str]], section: str = "Commands") -> type[LazyGroup]:
    """A :class:`LazyGroup` subclass over ``commands``, for ``@click.group(cls=...)``."""
    return type("LazyGroupOf" + section.title().replace(" ", ""), (LazyGroup,),
                {"commands_table": commands, "section": section})
