"""Strict JSON for everything dyadbench writes: no bare ``NaN``/``Infinity``, exact values kept.

JSON has no NaN or infinity; Python writes them as the bare words ``NaN``/``Infinity``, which most other
parsers (``jq``, JavaScript, Go, ``json.loads(..., parse_constant=...)``) refuse. :func:`dumps` writes
each non-finite number as ``null`` and, when the document is an object, records the exact value in a
last top-level member::

    "nonfinite": {"/metrics/rpcc_exp": "nan", "/per_clip/rows/3/5": "-inf"}

Keys are JSON Pointers (RFC 6901: ``/``-separated object keys and list indices, ``~`` written ``~0`` and
``/`` written ``~1``); values are ``"nan"``, ``"inf"`` or ``"-inf"``. The member is absent when every
number is finite. :func:`loads` reads both these files and older ones with bare ``NaN`` to the same
Python values: the pointed-to ``null`` becomes the float again and the member is removed.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np

#: Top-level member holding the exact non-finite values (see module docstring).
NONFINITE = "nonfinite"
_NAMES = {"nan": math.nan, "inf": math.inf, "-inf": -math.inf}


def dumps(obj: Any) -> str:
    """Indented strict JSON of ``obj`` (numpy scalars/arrays, tuples and paths converted), newline-ended.

    Raises ValueError if a non-finite number sits in a document that is not an object or that already
    has a ``nonfinite`` member (the exact value could not be recorded).
    """
    found: dict[str, str] = {}
    plain = _plain(obj, "", found)
    if found:
        if not isinstance(plain, dict) or NONFINITE in plain:
            raise ValueError(f"cannot record non-finite values at {', '.join(found)} in strict JSON")
        plain[NONFINITE] = found
    return json.dumps(plain, indent=2, allow_nan=False) + "\n"


def loads(text: str) -> Any:
    """Parse JSON written by :func:`dumps` or by plain ``json.dumps`` (bare ``NaN``); ValueError if the
    ``nonfinite`` member is malformed or names a value that is not ``null``."""
    doc = json.loads(text)
    if isinstance(doc, dict) and NONFINITE in doc:
        entries = doc.pop(NONFINITE)
        if not isinstance(entries, dict):
            raise ValueError(f"{NONFINITE!r} must be an object of JSON Pointer -> 'nan' | 'inf' | '-inf'")
        for pointer, name in entries.items():
            _restore(doc, pointer, name)
    return doc


def _plain(obj: Any, pointer: str, found: dict[str, str]) -> Any:
    """JSON-ready copy of ``obj``; non-finite floats become None and are recorded in ``found``."""
    if isinstance(obj, dict):
        return {k: _plain(v, f"{pointer}/{_escape(k)}", found) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_plain(v, f"{pointer}/{i}", found) for i, v in enumerate(obj)]
    if isinstance(obj, np.ndarray):
        return _plain(obj.tolist(), pointer, found)
    if isinstance(obj, np.generic):
        return _plain(obj.item(), pointer, found)
    if isinstance(obj, Path):
        return str(obj)
    if isinstance(obj, float) and not math.isfinite(obj):
        found[pointer] = "nan" if math.isnan(obj) else ("inf" if obj > 0 else "-inf")
        return None
    if obj is None or isinstance(obj, (str, int, float)):
        return obj
    raise TypeError(f"not JSON serialisable: {type(obj).__name__}")


def _escape(key: Any) -> str:
    """A pointer token for an object key, as json.dumps turns the key into a string."""
    text = key if isinstance(key, str) else json.dumps(key)
    return text.replace("~", "~0").replace("/", "~1")


def _restore(doc: Any, pointer: Any, name: Any) -> None:
    if name not in _NAMES or not isinstance(pointer, str) or not pointer.startswith("/"):
        raise ValueError(f"bad {NONFINITE!r} entry {pointer!r}: {name!r}")
    *parents, last = [t.replace("~1", "/").replace("~0", "~") for t in pointer[1:].split("/")]
    node = doc
    try:
        for token in parents:
            node = node[int(token)] if isinstance(node, list) else node[token]
        key = int(last) if isinstance(node, list) else last
        if node[key] is not None:
            raise ValueError(f"{NONFINITE!r} entry {pointer!r} names a value that is not null")
        node[key] = _NAMES[name]
    except (KeyError, IndexError, TypeError) as exc:
        raise ValueError(f"{NONFINITE!r} entry {pointer!r} names no value ({exc})") from None
