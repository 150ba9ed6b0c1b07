"""Predictions on disk: a folder of ``<stem>.npy`` files, or one ``.npz`` whose keys are the stems.

Layout-agnostic: the expected per-frame width is a parameter, so every suite reads its predictions
through :func:`open_predictions`. Arrays are read lazily, one at a time (a DualTalk-sized set does not
have to fit in memory), validated for shape and dtype with messages that name the file (and key);
NaN/inf values are let through so the scorer can exclude and list such predictions.
"""

from __future__ import annotations

import zipfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from dyadbench.arrays import check_motion, load_npy, load_npz
from dyadbench.errors import InputError


@dataclass(frozen=True)
class PredictionFile:
    """Where one prediction lives: ``path`` (a ``.npy``, or the ``.npz`` holding key ``stem``)."""

    stem: str
    path: Path
    in_archive: bool

    @property
    def name(self) -> str:
        """How messages name this prediction: ``dir/stem.npy`` or ``preds.npz[stem]``."""
        return f"{self.path}[{self.stem}]" if self.in_archive else str(self.path)

    def load(self, width: int | None) -> np.ndarray:
        """The (T, width) float64 array; NaN/inf kept. Bad shape, dtype or file -> InputError."""
        if self.in_archive:
            array = load_npz(self.path, [self.stem])[self.stem]
        else:
            array = load_npy(self.path)
        return check_motion(array, self.name, width, finite=False)


def open_predictions(path: str | Path) -> dict[str, PredictionFile]:
    """Index the predictions at ``path`` (a folder of ``.npy`` or one ``.npz``), sorted by stem.

    Nothing is loaded yet. An empty folder, an empty archive, an unreadable archive or any other kind
    of path raises :class:`InputError` naming it.
    """
    path = Path(path)
    if path.is_dir():
        files = {f.stem: PredictionFile(f.stem, f, False) for f in sorted(path.glob("*.npy"))}
        if not files:
            raise InputError(path, "no .npy predictions in this folder")
    elif path.is_file() and path.suffix == ".npz":
        files = {stem: PredictionFile(stem, path, True) for stem in sorted(_archive_keys(path))}
        if not files:
            raise InputError(path, "the archive holds no predictions")
    elif path.exists():
        raise InputError(path, "predictions must be a folder of .npy files or one .npz archive")
    else:
        raise InputError(path, "not found")
    return files


def _archive_keys(path: Path) -> list[str]:
    """Member names of an ``.npz`` without loading the arrays."""
    try:
        with zipfile.ZipFile(path) as archive:
            names = archive.namelist()
    except (zipfile.BadZipFile, OSError) as exc:
        raise InputError(path, f"unreadable .npz archive ({exc})") from None
    return [n[: -len(".npy")] for n in names if n.endswith(".npy")]
