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


def _kind(value: Any) -> str | None:
    """The type family a config value must keep: 'bool', 'number', 'str', 'tuple'; None = unchecked."""
    if isinstance(value, bool):
        return "bool"
    if isinstance(value, (int, float)):
        return "number"
    if isinstance(value, str):
        return "str"
    if isinstance(value, tuple):
        return "tuple"
    return None


def check_field_types(cfg: Any) -> None:
    """Refuse a field whose value is not of its default's kind (ints stay ints; a tuple holds numbers),
    so ``--set fsq_levels=8,5`` is a clear error rather than a string compared with numbers deep inside."""
    for f in fields(cfg):
        value, kind = getattr(cfg, f.name), _kind(f.default)
        if kind is None:
            continue
        int_only = isinstance(f.default, int) and not isinstance(f.default, bool)
        ok = {"bool": isinstance(value, bool),
              "number": isinstance(value, (int, float)) and not isinstance(value, bool)
              and (not int_only or isinstance(value, int)),
              "str": isinstance(value, str),
              "tuple": isinstance(value, tuple)
              and all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in value)}[kind]
        if not ok:
            example = f"[{','.join(map(str, f.default))}]" if kind == "tuple" else repr(f.default)
            raise ConfigError(f"{type(cfg).__name__}.{f.name} = {value!r} is not of the kind of its default "
                              f"{example} (tuples are JSON lists: --set {f.name}=[...])" if kind == "tuple" else
                              f"{type(cfg).__name__}.{f.name} = {value!r} is not of the kind of its default {example}")
