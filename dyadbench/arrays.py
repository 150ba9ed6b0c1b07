"""Validated reading of numeric arrays from ``.npy`` / ``.npz`` files, and the value checks every reader shares.

Everything here raises :class:`dyadbench.errors.InputError` naming the file (and key) and what was
wrong, instead of letting a numpy or zipfile traceback reach the user. Files are always opened with
``allow_pickle=False``: a pickled array is refused, never executed. A path that is a folder, a
symbolic link loop or a broken link is named as such (not "not found"); bytes that are not a NumPy
file are called that; an ``.npz`` holding two members of the same name is refused (which one a reader
would get is an accident of the zip library). The dtype and value checks (:func:`require_float`,
:func:`check_values`, :func:`nonfinite_problem`) are the ones :mod:`dyadbench.scoring.policy`
applies in every metric suite and every reader of ground truth, so their wording is the same everywhere.
"""

from __future__ import annotations

import errno
import math
import os
import stat
import zipfile
from pathlib import Path

import numpy as np

from dyadbench.errors import InputError

_READ_ERRORS = (ValueError, OSError, EOFError, zipfile.BadZipFile, KeyError)
_NPY_MAGIC = np.lib.format.MAGIC_PREFIX
_ZIP_MAGICS = (b"PK\x03\x04", b"PK\x05\x06")  # a zip archive with members / an empty one
#: Largest magnitude whose square is a finite float64 (about 1.34e154): beyond it, squared errors,
#: variances and covariances overflow to inf.
OVERFLOW_LIMIT = math.sqrt(np.finfo(np.float64).max)


def require_file(path: str | Path) -> Path:
    """``path`` when it is a regular file (or a link to one); otherwise an InputError saying what it is:
    a folder, a symbolic link loop, a broken link, unreadable, or not there."""
    path = Path(path)
    try:
        mode = path.stat().st_mode
    except OSError as exc:
        if exc.errno == errno.ELOOP:
            raise InputError(path, "symbolic link loop (following the link leads back to it)") from None
        if exc.errno == errno.EACCES:
            raise InputError(path, "cannot be read (permission denied)") from None
        if path.is_symlink():
            raise InputError(path, f"broken symbolic link (its target {os.readlink(path)} does not exist)") from None
        raise InputError(path, "file not found") from None
    if stat.S_ISDIR(mode):
        raise InputError(path, "is a folder, expected a file")
    if not stat.S_ISREG(mode):
        raise InputError(path, "is not a regular file")
    return path


def _describe_read_error(exc: Exception) -> str:
    text = str(exc)
    if "allow_pickle" in text or "Object arrays" in text:
        return "contains a pickled (object) array, which dyadbench refuses to load"
    return f"unreadable ({type(exc).__name__}: {text})"


def _open(path: Path) -> np.ndarray | np.lib.npyio.NpzFile:
    require_file(path)
    try:
        with open(path, "rb") as handle:
            head = handle.read(len(_NPY_MAGIC))
    except OSError as exc:
        raise InputError(path, f"cannot be read ({exc.strerror})") from None
    if not head.startswith((_NPY_MAGIC, *_ZIP_MAGICS)):
        raise InputError(path, "not a NumPy .npy/.npz file" + ("" if head else " (the file is empty)"))
    try:
        return np.load(path, allow_pickle=False)
    except _READ_ERRORS as exc:
        raise InputError(path, _describe_read_error(exc)) from None


def _refuse_duplicates(path: Path, keys: list[str]) -> None:
    repeated = sorted({k for k in keys if keys.count(k) > 1})
    if repeated:
        key = repeated[0]
        raise InputError(f"{path}[{key}]", f"the archive holds {keys.count(key)} arrays named {key!r} (duplicate "
                                           f"zip members); which one is meant is ambiguous, so none is read")


def load_npy(path: str | Path) -> np.ndarray:
    """Read one ``.npy`` array (no pickles). Missing, unreadable or non-``.npy`` files -> InputError."""
    path = Path(path)
    array = _open(path)
    if not isinstance(array, np.ndarray):
        raise InputError(path, "is an .npz archive, expected a single .npy array")
    return array


def load_npz(path: str | Path, keys: list[str] | None = None) -> dict[str, np.ndarray]:
    """Read the arrays of one ``.npz`` archive (no pickles) into a dict.

    ``keys`` restricts reading to those entries (each must exist); ``None`` reads all of them. An
    archive with two members of the same name is refused, whichever keys are read.
    """
    path = Path(path)
    archive = _open(path)
    if not isinstance(archive, np.lib.npyio.NpzFile):
        raise InputError(path, "is a single .npy array, expected an .npz archive")
    with archive:
        _refuse_duplicates(path, list(archive.files))
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


def npz_keys(path: str | Path) -> list[str]:
    """The array names of an ``.npz`` in archive order, without loading the arrays. A path that is not a
    readable zip archive, or an archive with two members of the same name, raises InputError."""
    path = require_file(path)
    try:
        with zipfile.ZipFile(path) as archive:
            names = archive.namelist()
    except (zipfile.BadZipFile, OSError) as exc:
        raise InputError(path, f"not a NumPy .npz archive ({exc})") from None
    keys = [n[: -len(".npy")] for n in names if n.endswith(".npy")]
    _refuse_duplicates(path, keys)
    return keys


def shape_problem(shape: tuple[int, ...], expected: str, transposed: bool = False) -> str:
    """The wording of every shape error: ``expected 7 values per frame (T, 7), got shape (7, 1125)``, plus a
    hint when the array looks transposed (the caller knows)."""
    return f"expected {expected}, got shape {tuple(shape)}" + ("; it looks transposed" if transposed else "")


def require_float(array: np.ndarray, source: str | Path) -> None:
    """Real floating-point values only: int, bool, complex, object or string arrays raise InputError."""
    if np.asarray(array).dtype.kind != "f":
        raise InputError(source, f"expected real floating-point values, got dtype {np.asarray(array).dtype}")


def nonfinite_count(array: np.ndarray) -> int:
    """Number of NaN/inf entries of ``array``."""
    return int(array.size - np.count_nonzero(np.isfinite(array)))


def nonfinite_problem(array: np.ndarray) -> str | None:
    """``"3 NaN/inf values (first at index (4, 2))"``, or None when every value is finite."""
    bad = nonfinite_count(array)
    if not bad:
        return None
    first = tuple(int(i) for i in np.argwhere(~np.isfinite(array))[0])
    return f"{bad} NaN/inf values (first at index {first})"


def require_finite(array: np.ndarray, source: str | Path) -> None:
    """NaN/inf values raise InputError naming ``source``, how many there are and where the first is."""
    problem = nonfinite_problem(array)
    if problem:
        raise InputError(source, f"contains {problem}")


def max_abs(array: np.ndarray) -> float:
    """Largest magnitude among the finite values of ``array`` (0 when it has none)."""
    a = np.asarray(array)
    finite = np.abs(a[np.isfinite(a)])
    return float(finite.max()) if finite.size else 0.0


def require_no_overflow(array: np.ndarray, source: str | Path) -> None:
    """Finite values whose squares overflow float64 (|x| > :data:`OVERFLOW_LIMIT`) raise InputError."""
    largest = max_abs(array)
    if largest > OVERFLOW_LIMIT:
        raise InputError(source, f"has values up to {largest:.3g} in magnitude, whose squares overflow float64 "
                                 f"(|x| > {OVERFLOW_LIMIT:.3g}); no metric can be computed from them")


def check_values(array: np.ndarray, source: str | Path) -> None:
    """The rule for ground truth (:mod:`dyadbench.scoring.policy`): NaN/inf values, or finite values whose
    squares overflow float64, raise InputError naming ``source``."""
    require_finite(array, source)
    require_no_overflow(array, source)


def check_motion(array: np.ndarray, source: str | Path, width: int | None = None, *,
                 finite: bool = True) -> np.ndarray:
    """Validate a (T, width) real floating-point motion array; return it as float64.

    Checks, in order: shape, dtype, then (``finite=True``, ground truth) NaN/inf and overflowing values.
    ``width=None`` accepts any width. ``finite=False`` lets every value through (a scorer applies the
    prediction rules of :mod:`dyadbench.scoring.policy`).
    """
    array = np.asarray(array)
    if array.ndim != 2:
        raise InputError(source, f"expected a 2-d (frames, {width or 'dims'}) array, got shape {array.shape}")
    if width is not None and array.shape[1] != width:
        raise InputError(source, shape_problem(array.shape, f"{width} values per frame (T, {width})",
                                               transposed=array.shape[0] == width))
    if array.shape[0] == 0:
        raise InputError(source, f"has no frames (shape {array.shape})")
    require_float(array, source)
    if finite:
        check_values(array, source)
    return array.astype(np.float64, copy=False)
