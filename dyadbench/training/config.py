"""Model configs (frozen dataclasses) as plain dicts in checkpoints and results, and back, and the checks
of their fields: each value of its default's kind (:func:`check_field_types`) and, for a numeric field
declared with :func:`bounded`, within its :class:`Domain` (:func:`check_field_domains`)."""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field, fields
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


@dataclass(frozen=True)
class Domain:
    """The finite numbers a config field may take: ``low``/``high`` bounds (None: unbounded), each open
    (excluded) or closed. A tuple field's domain applies to each of its numbers; None passes (optional)."""

    low: float | None = None
    high: float | None = None
    low_open: bool = False
    high_open: bool = False

    def contains(self, value: Any) -> bool:
        if not _is_number(value) or not math.isfinite(value):
            return False
        above = self.low is None or (value > self.low if self.low_open else value >= self.low)
        below = self.high is None or (value < self.high if self.high_open else value <= self.high)
        return above and below

    def __str__(self) -> str:
        if self.high is None:
            return f"{'>' if self.low_open else '>='} {self.low}"
        return f"in {'(' if self.low_open else '['}{self.low}, {self.high}{')' if self.high_open else ']'}"


POSITIVE = Domain(0, low_open=True)  # sizes, counts, steps, learning rates, temperatures
NON_NEGATIVE = Domain(0)  # loss weights, layer counts, radii (0 = off)
PROBABILITY = Domain(0, 1)  # probabilities and fractions of a run
BELOW_ONE = Domain(0, 1, high_open=True)  # decay rates (EMA, Adam betas)


def bounded(default: Any, domain: Domain) -> Any:
    """A dataclass field with ``default`` whose values must lie in ``domain`` (:func:`check_field_domains`)."""
    return field(default=default, metadata={"domain": domain})


def check_field_domains(cfg: Any) -> None:
    """Refuse a numeric field outside the domain declared with :func:`bounded` (NaN and inf included), e.g.
    ``--set steps=-1`` or ``--set dropout=1.5``, naming the field and its domain. Run after
    :func:`check_field_types` (the values are numbers then)."""
    for f in fields(cfg):
        domain = f.metadata.get("domain")
        value = getattr(cfg, f.name)
        if domain is None or value is None:
            continue
        if not all(domain.contains(v) for v in (value if isinstance(value, tuple) else (value,))):
            raise ConfigError(f"{type(cfg).__name__}.{f.name} = {value!r} must be a finite number {domain}")
