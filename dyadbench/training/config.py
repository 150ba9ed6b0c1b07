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


def _is_number(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _same_kind(default: Any, value: Any) -> bool:
    """Whether ``value`` may stand for a field whose default is ``default``: bools stay bools, ints stay ints,
    floats take any number, strings stay strings, tuples hold numbers; other defaults (None) are unchecked."""
    if isinstance(default, bool):
        return isinstance(value, bool)
    if isinstance(default, int):
        return isinstance(value, int) and not isinstance(value, bool)
    if isinstance(default, float):
        return _is_number(value)
    if isinstance(default, str):
        return isinstance(value, str)
    if isinstance(default, tuple):
        return isinstance(value, tuple) and all(_is_number(v) for v in value)
    return True


def check_field_types(cfg: Any) -> None:
    """Refuse a field whose value is not of its default's kind, so ``--set fsq_levels=8,5`` (a string) is a
    clear error naming the field rather than a string compared with numbers deep inside."""
    for f in fields(cfg):
        value = getattr(cfg, f.name)
        if _same_kind(f.default, value):
            continue
        tuple_field = isinstance(f.default, tuple)
        example = f"[{','.join(map(str, f.default))}]" if tuple_field else repr(f.default)
        hint = f" (tuples are JSON lists: --set {f.name}=[...])" if tuple_field else ""
        raise ConfigError(f"{type(cfg).__name__}.{f.name} = {value!r} is not of the kind of its default "
                          f"{example}{hint}")
