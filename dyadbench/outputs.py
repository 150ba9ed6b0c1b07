"""Output paths of dyadbench commands: checked before any work starts, and output folders owned by one run.

- :func:`check_folder`, :func:`check_file`, :func:`check_cache`: fail before any work when an output
  path cannot be written (a file where a folder is needed, a read-only folder, a name the file system
  refuses as too long, a cache path that is a file), with one line naming the path. Missing folders are
  created for the check and removed again, and a probe file is written and removed: the honest test.
- :class:`OwnedFolder` / :func:`owned_folder`: an output folder written by one run only. The run writes
  into a fresh temporary sibling folder, created at once (so an unwritable output fails before the work;
  :meth:`OwnedFolder.check` checks the same earlier still); when the run completes, the marker :data:`MARKER` is added and the folder swapped into place (the previous
  folder moved aside, the new one renamed in, the old one removed). On any failure or interruption the
  previous output stays untouched and the temporary folder is removed. A non-empty folder that is not a
  previous output of the same kind is refused unless ``force``.
- :func:`kept_on_failure`: when writing a computed result fails after the work, the result is saved
  under the system's temporary folder and the error says where.
"""

from __future__ import annotations

import contextlib
import json
import os
import secrets
import shutil
import tempfile
from pathlib import Path
from typing import Callable, Iterator

from dyadbench import __version__, atomic
from dyadbench.errors import ConfigError, OutputError
from dyadbench.paths import cache_location

#: Marker file of a folder written by :func:`owned_folder`: ``{"kind": ..., "dyadbench": version}``.
MARKER = ".dyadbench-output"  # JSON, named so that no "*.json" search (result files, ...) picks it up
#: Infixes of the temporary siblings (new output being written, previous output being removed).
STAGING, ASIDE = ".dyadbench-tmp-", ".dyadbench-old-"
_NAME_KEPT = 40  # characters of the output's name kept in its siblings' names


def _problem(exc: OSError) -> str:
    return exc.strerror or str(exc)


def _make_folders(path: Path, label: str) -> list[Path]:
    """Create ``path`` and its missing parents; return the folders created (outermost first)."""
    missing = []
    probe = path
    while not os.path.isdir(probe):
        if os.path.lexists(probe):
            raise ConfigError(f"{label}: {probe} exists and is not a folder")
        missing.append(probe)
        probe = probe.parent
    created: list[Path] = []
    try:
        for folder in reversed(missing):
            os.mkdir(folder)
            created.append(folder)
    except OSError as exc:
        _remove_folders(created)
        raise ConfigError(f"{label}: cannot create it ({_problem(exc)})") from None
    return created


def _remove_folders(created: list[Path]) -> None:
    """Remove the (empty) folders :func:`_make_folders` created, innermost first."""
    for folder in reversed(created):
        with contextlib.suppress(OSError):
            os.rmdir(folder)


@contextlib.contextmanager
def _probed(folder: Path, label: str) -> Iterator[None]:
    """Make ``folder`` exist for the block (removing what was created afterwards); OSError -> ConfigError."""
    created = _make_folders(folder, label)
    try:
        yield
    except OSError as exc:
        raise ConfigError(f"{label}: cannot write there ({_problem(exc)})") from None
    finally:
        _remove_folders(created)


def _probe_write(folder: Path) -> None:
    """Create and remove a file in ``folder`` (OSError when it cannot be written)."""
    fd, probe = tempfile.mkstemp(prefix=".dyadbench-probe-", dir=folder)
    os.close(fd)
    os.unlink(probe)


def check_folder(path: str | Path, label: str) -> Path:
    """Fail now, with a ConfigError led by ``label``, unless ``path`` is or can become a writable folder."""
    path = Path(path)
    with _probed(path, label):
        _probe_write(path)
    return path


def check_file(path: str | Path, label: str) -> Path:
    """Fail now, with a ConfigError led by ``label``, unless the file ``path`` can be written."""
    path = Path(path)
    if os.path.isdir(path):
        raise ConfigError(f"{label}: it is a folder, not a file")
    with _probed(path.parent, label):
        if os.path.lexists(path):
            _probe_write(path.parent)
        else:  # create it once: the name itself is accepted (not too long, ...)
            os.close(os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL))
            os.unlink(path)
    return path


def check_cache() -> Path:
    """Fail now unless the cache folder (:func:`dyadbench.paths.cache_dir`) is or can become writable."""
    path, label = cache_location()
    return check_folder(path, label)


def is_owned(folder: Path, kind: str) -> bool:
    """True when ``folder`` holds the :data:`MARKER` of a completed :func:`owned_folder` run of ``kind``."""
    try:
        return json.loads((folder / MARKER).read_text(encoding="utf-8")).get("kind") == kind
    except (OSError, ValueError, AttributeError):
        return False


def _claim(path: Path, kind: str, force: bool, label: str, legacy: Callable[[Path], bool] | None) -> None:
    """Refuse an existing ``path`` that is not a folder, or a non-empty folder that is not ours (unless force)."""
    if not os.path.lexists(path):
        return
    if not os.path.isdir(path):
        raise ConfigError(f"{label}: it exists and is not a folder")
    try:
        empty = not os.listdir(path)
    except OSError as exc:
        raise ConfigError(f"{label}: cannot read it ({_problem(exc)})") from None
    if empty or force or is_owned(path, kind) or (legacy is not None and legacy(path)):
        return
    raise ConfigError(f"{label}: the folder holds files that are not a previous dyadbench {kind} output; "
                      f"refusing to replace them (use --force to replace the folder, or choose an empty or new one)")


class OwnedFolder:
    """An output folder written by one run only (see the module docstring).

    ``kind`` names what the folder holds (recorded in :data:`MARKER`; only a folder of the same kind,
    an empty one, or with ``force`` any folder, is replaced). ``legacy(folder)`` recognises outputs
    written before the marker existed. ``label`` leads error messages (default: ``output folder PATH``).
    A symlinked folder is written where it points.
    """

    def __init__(self, path: str | Path, kind: str, *, force: bool = False, label: str | None = None,
                 legacy: Callable[[Path], bool] | None = None):
        self.target = Path(os.path.realpath(path))
        self.kind, self.force, self.legacy = kind, force, legacy
        self.label = label or f"output folder {path}"

    def check(self) -> "OwnedFolder":
        """Fail now (ConfigError) unless :meth:`writing` could start: the folder is absent, empty or
        replaceable, and its parent is a writable folder that accepts its name."""
        _claim(self.target, self.kind, self.force, self.label, self.legacy)
        with _probed(self.target.parent, self.label):
            if os.path.lexists(self.target):
                _probe_write(self.target.parent)
            else:  # the name itself is accepted (not too long, ...)
                os.mkdir(self.target)
                os.rmdir(self.target)
        return self

    @contextlib.contextmanager
    def writing(self) -> Iterator[Path]:
        """Yield a fresh temporary sibling folder for the run's output; swap it onto the folder at the end.

        Raises ConfigError before the block runs when the folder cannot be written, and OutputError
        (naming the complete temporary folder, which is then kept) when the finished output cannot be
        moved into place. On any exception in the block the temporary folder is removed.
        """
        target, label = self.target, self.label
        self.check()
        created = _make_folders(target.parent, label)
        try:
            staging = atomic.make_temp_dir(target.parent, prefix=f".{target.name[:_NAME_KEPT]}{STAGING}")
        except OSError as exc:
            _remove_folders(created)
            raise ConfigError(f"{label}: cannot write there ({_problem(exc)})") from None
        try:
            yield staging
            atomic.write_json(staging / MARKER, {"kind": self.kind, "dyadbench": __version__})
        except BaseException:
            shutil.rmtree(staging, ignore_errors=True)
            _remove_folders(created)
            raise
        _swap(staging, target, label)


def owned_folder(path: str | Path, kind: str, **options) -> contextlib.AbstractContextManager[Path]:
    """``OwnedFolder(path, kind, **options).writing()``: the temporary folder a run writes its output in."""
    return OwnedFolder(path, kind, **options).writing()


def _swap(staging: Path, target: Path, label: str) -> None:
    """Move the previous ``target`` aside, rename ``staging`` onto it, remove the previous one.

    If the new folder cannot be moved in, the previous one is put back and ``staging`` is kept.
    """
    aside = None
    try:
        if os.path.lexists(target):
            aside = target.with_name(f".{target.name[:_NAME_KEPT]}{ASIDE}{secrets.token_hex(4)}")
            os.rename(target, aside)
        os.rename(staging, target)
    except BaseException as exc:
        if aside is not None and not os.path.lexists(target):
            os.rename(aside, target)
        if isinstance(exc, OSError):
            raise OutputError(f"{label}: could not move the finished output into place ({_problem(exc)}); "
                              f"it is complete in {staging}") from None
        shutil.rmtree(staging, ignore_errors=True)
        raise
    if aside is not None:
        shutil.rmtree(aside, ignore_errors=True)


def keep_text(text: str, name: str) -> Path:
    """Save ``text`` as a new file under the system's temporary folder, named after ``name``."""
    stem, suffix = os.path.splitext(os.path.basename(name))
    fd, kept = tempfile.mkstemp(prefix=f"dyadbench-recovered-{stem[:_NAME_KEPT]}-", suffix=suffix)
    with os.fdopen(fd, "w", encoding="utf-8") as f:
        f.write(text)
    return Path(kept)


@contextlib.contextmanager
def kept_on_failure(destination: str | Path, text: Callable[[], str]) -> Iterator[None]:
    """Turn an OSError raised while writing ``destination`` into an OutputError that says where ``text()``
    (the computed result) was saved instead, so finished work is never lost to a failed write."""
    try:
        yield
    except OSError as exc:
        try:
            where = f"the computed result is kept in {keep_text(text(), str(destination))}"
        except OSError as again:
            where = f"the computed result could not be kept either ({_problem(again)})"
        raise OutputError(f"{destination}: could not write it ({_problem(exc)}); {where}") from None
