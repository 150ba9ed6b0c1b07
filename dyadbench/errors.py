"""Error types raised on bad user input.

Every error that reaches a user names the file (or array) and what was wrong with it; the CLI prints
the message without a traceback. Every error type pickles to itself (same type, same message), so an
error raised in a worker process reaches the user exactly as it would with one process.
"""

from __future__ import annotations

from pathlib import Path


class DyadbenchError(Exception):
    """Base class of all user-facing errors."""


class InputError(DyadbenchError, ValueError):
    """An input file or array is missing, malformed or inconsistent.

    ``source`` names the file or array the problem is in; it leads the message.
    """

    def __init__(self, source: str | Path | None, problem: str):
        self.source = str(source) if source is not None else None
        self.problem = problem
        super().__init__(f"{self.source}: {problem}" if self.source else problem)

    def __reduce__(self):
        # Rebuilt from (source, problem), not from the formatted message, so the error survives the trip
        # back from a worker process (pickling) unchanged.
        return type(self), (self.source, self.problem)


class ConfigError(DyadbenchError, ValueError):
    """An option, name or parameter is invalid (unknown model, bad context length, ...)."""


class OutputError(DyadbenchError):
    """A finished result could not be written where asked; the message says where it was kept instead."""
