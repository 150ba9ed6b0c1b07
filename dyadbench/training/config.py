"""Model configs (frozen dataclasses) as plain dicts in checkpoints and results, and back."""

from __future__ import annotations

from dataclasses import asdict, fields
from typing import Any, TypeVar

from dyadbench.errors import ConfigError

T = TypeVar("T")


def config_to_dict(cfg: Any) -> dict:
    """Plain dict of a config dataclass; tuples become lists (JSON-friendly)."""
    return {k: list(v) if isinstance(v, tuple) else v for k, v in asdict(cfg).items()}


def config_from_dict(cls: type[T], data: dict) -> T:
    """Rebuild a config saved by :func:`config_to_dict`: lists become tuples again; an unknown key is an
    error (the dict comes from another model or a newer version)."""
    known = {f.name for f in fields(cls)}
    unknown = set(data) - known
    if unknown:
        raise ConfigError(f"unknown {cls.__name__} fields: {sorted(unknown)}")
    return cls(**{k: tuple(v) if isinstance(v, list) else v for k, v in data.items()})
