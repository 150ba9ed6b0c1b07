"""Validated reading of numeric arrays from ``.npy`` / ``.npz`` files.

Everything here raises :class:`dyadbench.errors.InputError` naming the file (and key) and what was
wrong, instead of letting a numpy or zipfile traceback reach the user. Files are always opened with
``allow_pickle=False``: a pickled array is refused, never executed.
"""

from __future__ import annotations

import zipfile
from pathlib import Path

import numpy as np

from dyadbench.errors import InputError

_READ_ERRORS = (ValueError, OSError, EOFError, zipfile.BadZipFile, KeyError)


def _describe_read_error(exc: Exception) -> str:
    text = str(exc)
    if "allow_pickle" in text or "Object arrays" in text:
        return "contains a pickled (object) array, which dyadbench refuses to load"
    return f"unreadable ({type(exc).__name__}: {text})"


def _open(path: Path) -> np.ndarray | np.lib.npyio.NpzFile:
    if not path.is_file():
        raise InputError(path, "file not found")
    try:
        return np.load(path, allow_pickle=False)
    except _READ_ERRORS as exc:
        raise InputError(path, _describe_read_error(exc)) from None


def load_npy(path: str | Path) -> np.ndarray:
    """Read one ``.npy`` array (no pickles). Missing, unreadable or non-``.npy`` files -> InputError."""
    path = Path(path)
    array = _open(path)
    if not isinstance(array, np.ndarray):
        raise InputError(path, "is an .npz archive, expected a single .npy array")
    return array


def load_npz(path: str | Path, keys: list[str] | None = None) -> dict[str, np.ndarray]:
    """Read the arrays of one ``.npz`` archive (no pickles) into a dict.

    ``keys`` restricts reading to those entries (each must exist); ``None`` reads all of them.
    """
    path = Path(path)
    archive = _open(path)
    if not isinstance(archive, np.lib.npyio.NpzFile):
        raise InputError(path, "is a single .npy array, expected an .npz archive")
    with archive:
        wanted = list(archive.files) if keys is None else keys
        missing = [k for k in wanted if k not in archive.files]
        if missing:
            raise InputError(path, f"missing key(s) {', '.join(missing)} (has: {', '.join(archive.files)})")
        arrays = {}
        for key in wanted:
            try:
                arrays[key] = archive[key]
            except _READ_ERRORS as exc:
                raise InputError(f"{path}[{key}]", _describe_read_error(exc)) from None
    return arrays


def check_motion(array: np.ndarray, source: str | Path, width: int | None = None, *,
                 finite: bool = True) -> np.ndarray:
    """Validate a (T, width) real floating-point motion array; return it as float64.

    ``width=None`` accepts any width. ``finite=False`` lets NaN/inf through (the caller decides what
    to do with them, e.g. exclude the prediction and list it).
    """
    array = np.asarray(array)
    if array.ndim != 2:
        raise InputError(source, f"expected a 2-d (frames, {width or 'dims'}) array, got shape {array.shape}")
    if width is not None and array.shape[1] != width:
        raise InputError(source, f"expected {width} values per frame, got shape {array.shape}")
    if array.shape[0] == 0:
        raise InputError(source, f"has no frames (shape {array.shape})")
    if array.dtype.kind != "f":
        raise InputError(source, f"expected a floating-point array, got dtype {array.dtype}")
    if finite and nonfinite_count(array):
        raise InputError(source, f"contains {nonfinite_count(array)} NaN/inf values")
    return array.astype(np.float64, copy=False)


def nonfinite_count(array: np.ndarray) -> int:
    """Number of NaN/inf entries of ``array``."""
    return int(array.size - np.count_nonzero(np.isfinite(array)))
