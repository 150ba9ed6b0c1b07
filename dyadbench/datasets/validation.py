"""The outcome of checking a dataset folder: errors and warnings, each naming its file."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from dyadbench.errors import InputError


@dataclass
class ValidationReport:
    """``ok`` when there is no error. ``checked`` counts the items (clips, sessions) examined."""

    folder: str
    layout: str
    checked: int = 0
    errors: list[str] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)

    @property
    def ok(self) -> bool:
        return not self.errors

    def error(self, source: str | Path, problem: str) -> None:
        self.errors.append(f"{source}: {problem}")

    def warn(self, source: str | Path, problem: str) -> None:
        self.warnings.append(f"{source}: {problem}")

    def add(self, exc: InputError) -> None:
        """Record a caught :class:`InputError` (its message already names the file)."""
        self.errors.append(str(exc))

    def summary(self) -> str:
        verdict = "OK" if self.ok else "PROBLEMS FOUND"
        head = (f"{self.folder} [{self.layout}]: {self.checked} checked, {len(self.errors)} errors, "
                f"{len(self.warnings)} warnings: {verdict}")
        return "\n".join([head] + [f"error: {e}" for e in self.errors] + [f"warning: {w}" for w in self.warnings])

    def as_dict(self) -> dict:
        return {"folder": self.folder, "layout": self.layout, "checked": self.checked, "ok": self.ok,
                "errors": list(self.errors), "warnings": list(self.warnings)}
