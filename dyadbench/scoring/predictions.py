"""Predictions on disk: a folder of ``<stem>.npy`` files, or one ``.npz`` whose keys are the stems.

Layout-agnostic: the expected per-frame width is a parameter, so every suite reads its predictions
through :func:`open_predictions` (REACT's nested ``<speaker path>.npy`` folders with ``recursive=True``).
Arrays are read lazily, one at a time (a DualTalk-sized set does not have to fit in memory), validated
for shape and dtype with messages that name the file (and key); NaN/inf values are let through so the
scorer can exclude and list such predictions (:mod:`dyadbench.scoring.policy`).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from dyadbench.arrays import check_motion, load_npy, load_npz, npz_keys, require_file
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

    def read(self) -> np.ndarray:
        """The stored array as it is (no shape or dtype check). A bad file -> InputError."""
        return load_npz(self.path, [self.stem])[self.stem] if self.in_archive else load_npy(self.path)

    def load(self, width: int | None) -> np.ndarray:
        """The (T, width) float64 array; NaN/inf kept. Bad shape, dtype or file -> InputError."""
        return check_motion(self.read(), self.name, width, finite=False)


def open_predictions(path: str | Path, *, recursive: bool = False) -> dict[str, PredictionFile]:
    """Index the predictions at ``path`` (a folder of ``.npy`` or one ``.npz``), sorted by stem.

    ``recursive``: the folder's ``.npy`` files at any depth, each named by its relative path without
    the suffix (``NoXI/<session>/Expert_video/3``).

    Nothing is loaded yet. An empty folder, an empty archive, an unreadable archive (or one holding two
    arrays of the same name) or any other kind of path raises :class:`InputError` naming it.
    """
    path = Path(path)
    if path.is_dir():
        found = sorted(path.rglob("*.npy") if recursive else path.glob("*.npy"))
        stems = [f.relative_to(path).with_suffix("").as_posix() for f in found]
        files = {stem: PredictionFile(stem, f, False) for stem, f in zip(stems, found)}
        if not files:
            raise InputError(path, "no .npy predictions in this folder")
        return files
    require_file(path)
    if path.suffix != ".npz":
        raise InputError(path, "predictions must be a folder of .npy files or one .npz archive")
    files = {stem: PredictionFile(stem, path, True) for stem in sorted(npz_keys(path))}
    if not files:
        raise InputError(path, "the archive holds no predictions")
    return files
