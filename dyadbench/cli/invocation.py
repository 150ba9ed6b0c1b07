"""The command line a run was started with, as the user typed it: what checkpoints record as ``command``.

The root ``dyadbench`` group keeps the arguments it was given (:data:`ARGV_KEY` in the click context's
``meta``, shared by every sub-command's context), so the record is right however the CLI was entered: the
``dyadbench`` script, ``python -m dyadbench``, or ``main([...])`` / click's test runner from Python, where
``sys.argv`` belongs to the calling program.
"""

from __future__ import annotations

import shlex

import click

ARGV_KEY = "dyadbench.argv"
PROGRAM = "dyadbench"


def recorded_command() -> str | None:
    """``dyadbench <args>`` of the running command, or None outside a ``dyadbench`` invocation (a sub-command
    called directly from Python, which the root group never saw)."""
    ctx = click.get_current_context(silent=True)
    argv = ctx.meta.get(ARGV_KEY) if ctx is not None else None
    return None if argv is None else shlex.join([PROGRAM, *argv])
