"""Atomic writes: a result file is either absent, the previous version, or complete.

Data is written to a temporary file in the destination folder and moved into place with
:func:`os.replace`, which is atomic on POSIX and Windows file systems.

Files and folders get the mode a plain ``open()``/``mkdir()`` would give them (``0o666`` or
``0o777`` less the process umask), not the private ``0o600``/``0o700`` of :mod:`tempfile`, so
results and leaderboards are readable by whoever could read a file the user wrote by hand.
"""

from __future__ import annotations

import contextlib
import functools
import io
import os
import tempfile
from pathlib import Path
from typing import Any, Callable, Iterator, Mapping

import numpy as np

from dyadbench import strict_json


@functools.lru_cache(maxsize=1)
def umask() -> int:
    """The process umask, read once (it is process-global and can only be read by setting it)."""
    old = os.umask(0)
    os.umask(old)
    return old


def file_mode() -> int:
    """The mode ``open(path, "w")`` gives a new file: ``0o666`` less the umask."""
    return 0o666 & ~umask()


def dir_mode() -> int:
    """The mode ``mkdir`` gives a new folder: ``0o777`` less the umask."""
    return 0o777 & ~umask()


def make_temp_dir(parent: str | Path, prefix: str) -> Path:
    """Create a fresh folder in ``parent`` (created if missing) with the mode ``mkdir`` would give.

    Use it for output built aside and later moved into place with :func:`os.replace`.
    """
    parent = Path(parent)
    parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=prefix, dir=parent))
    os.chmod(tmp, dir_mode())
    return tmp


@contextlib.contextmanager
def atomic_path(path: str | Path) -> Iterator[Path]:
    """Yield a temporary path beside ``path``; on success move it onto ``path``, else delete it.

    The temporary file (hence ``path``) has :func:`file_mode`.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    os.close(fd)
    tmp_path = Path(tmp)
    try:
        os.chmod(tmp_path, file_mode())
        yield tmp_path
        os.replace(tmp_path, path)
    finally:
        if tmp_path.exists():
            tmp_path.unlink()


def write_bytes(path: str | Path, data: bytes) -> Path:
    with atomic_path(path) as tmp:
        tmp.write_bytes(data)
    return Path(path)


def write_text(path: str | Path, text: str) -> Path:
    return write_bytes(path, text.encode("utf-8"))


def write_texts(files: Mapping[Path, str]) -> list[Path]:
    """Write several text files as one set: every temporary file is complete before the first is moved
    into place, so an error while writing any of them leaves all of them as they were."""
    with contextlib.ExitStack() as stack:
        for path, text in files.items():
            stack.enter_context(atomic_path(path)).write_bytes(text.encode("utf-8"))
    return [Path(p) for p in files]


def to_json(obj: Any) -> str:
    """Strict, indented JSON (NaN/inf as ``null``, exact values kept: see :mod:`dyadbench.strict_json`)."""
    return strict_json.dumps(obj)


def write_json(path: str | Path, obj: Any) -> Path:
    return write_text(path, to_json(obj))


def write_with(path: str | Path, writer: Callable[[Path], None]) -> Path:
    """Run ``writer(tmp_path)`` and atomically move the result onto ``path``."""
    with atomic_path(path) as tmp:
        writer(tmp)
    return Path(path)


def save_npz(path: str | Path, **arrays: np.ndarray) -> Path:
    """Atomic, uncompressed ``np.savez`` (byte-for-byte deterministic for equal inputs)."""
    buf = io.BytesIO()
    np.savez(buf, **arrays)
    return write_bytes(path, buf.getvalue())


def save_npy(path: str | Path, array: np.ndarray) -> Path:
    buf = io.BytesIO()
    np.save(buf, array)
    return write_bytes(path, buf.getvalue())
