"""Seamless Interaction files: discovery of participant bundles in both layouts, pairing into dyads.

A participant bundle is one file stem ``V<vendor>_S<session>_I<interaction>_P<participant>`` of one
``<root>/<label>/<split>`` folder, in either layout of the corpus (both accepted, found by globbing):

- **bundle**: ``<label>/<split>/**/<stem>.npz`` with ``<stem>.wav`` beside it (download tools add numbered
  sub-folders; they are never assumed);
- **per-modality**: ``<label>/<split>/audio/<stem>.wav`` and one ``<group>/<name>/<stem>.npy`` per npz key
  ``<group>:<name>`` (``movement/expression/<stem>.npy`` holds ``movement:expression``).

A dyad is the set of stems sharing ``V_S_I``. :func:`discover` lists them without reading any array;
:func:`bundle_frames` reads only the npy headers of the movement features (frame counts), so checking
thousands of files is cheap. Labels ``improvised`` / ``naturalistic``, splits ``train`` / ``dev`` / ``test``.
"""

from __future__ import annotations

import re
import zipfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from dyadbench.arrays import load_npy, load_npz
from dyadbench.errors import InputError

LABELS = ("improvised", "naturalistic")
SPLITS = ("train", "dev", "test")
STEM = re.compile(r"^(?P<dyad>V(?P<vendor>\d+)_S\d+_I\d+)_(?P<participant>P\d+)$")
MODALITY_AUDIO = "audio"
VALID_KEY = "movement:is_valid"


@dataclass(frozen=True)
class Bundle:
    """One participant's files: an ``.npz`` (bundle layout) or a folder of per-key ``.npy`` (per-modality)."""

    stem: str
    label: str
    split: str
    wav: Path | None
    npz: Path | None = None
    modality_root: Path | None = None  # <label>/<split> of the per-modality layout
    keys: tuple[str, ...] = ()  # npz keys present (per-modality: those with a file)

    @property
    def dyad(self) -> str:
        return STEM.match(self.stem)["dyad"]

    @property
    def participant(self) -> str:
        return STEM.match(self.stem)["participant"]

    @property
    def vendor(self) -> str:
        return f"V{STEM.match(self.stem)['vendor']}"

    @property
    def source(self) -> Path:
        """How messages name this bundle's features: the npz, or the per-modality movement folder."""
        return self.npz if self.npz is not None else self.modality_root / "movement" / f"*/{self.stem}.npy"

    def key_path(self, key: str) -> Path:
        group, _, name = key.partition(":")
        return self.modality_root / group / name / f"{self.stem}.npy"

    def read(self, keys: list[str]) -> dict[str, np.ndarray]:
        """The arrays of ``keys`` (each must be present); errors name the file."""
        missing = [k for k in keys if k not in self.keys]
        if missing:
            raise InputError(self.source, f"has no {', '.join(missing)}")
        if self.npz is not None:
            return load_npz(self.npz, keys)
        return {k: load_npy(self.key_path(k)) for k in keys}


def _header_shape(handle) -> tuple[int, ...]:
    version = np.lib.format.read_magic(handle)
    reader = np.lib.format.read_array_header_1_0 if version == (1, 0) else np.lib.format.read_array_header_2_0
    return reader(handle)[0]


def frames_of(bundle: Bundle, key: str = VALID_KEY) -> int:
    """N of ``key`` from its npy header only (no data read); errors name the file."""
    try:
        if bundle.npz is not None:
            with zipfile.ZipFile(bundle.npz) as archive, archive.open(f"{key}.npy") as member:
                shape = _header_shape(member)
        else:
            with open(bundle.key_path(key), "rb") as handle:
                shape = _header_shape(handle)
    except (OSError, ValueError, KeyError, zipfile.BadZipFile) as exc:
        raise InputError(bundle.source, f"unreadable {key} ({exc})") from None
    return int(shape[0]) if shape else 0


@dataclass
class Discovery:
    """Every bundle of some ``<label>/<split>`` folders, grouped by dyad, with the pairing problems found."""

    bundles: dict[str, list[Bundle]] = field(default_factory=dict)  # dyad -> bundles (sorted by stem)
    problems: list[str] = field(default_factory=list)  # "<file>: <problem>" of files that pair with nothing


def _npz_keys(path: Path) -> tuple[str, ...]:
    try:
        with zipfile.ZipFile(path) as archive:
            return tuple(n[:-len(".npy")] for n in archive.namelist() if n.endswith(".npy"))
    except (OSError, zipfile.BadZipFile) as exc:
        raise InputError(path, f"not a readable .npz archive ({exc})") from None


def _split_bundles(folder: Path, label: str, split: str, problems: list[str]) -> list[Bundle]:
    found: dict[str, Bundle] = {}
    modality_keys: dict[str, list[str]] = {}
    for npy in sorted(folder.glob("*/*/*.npy")):
        modality_keys.setdefault(npy.stem, []).append(f"{npy.parent.parent.name}:{npy.parent.name}")
    audio_dir = folder / MODALITY_AUDIO
    for stem, keys in modality_keys.items():
        wav = audio_dir / f"{stem}.wav"
        found[stem] = Bundle(stem, label, split, wav if wav.is_file() else None, modality_root=folder,
                             keys=tuple(sorted(keys)))
    for npz in sorted(folder.rglob("*.npz")):
        if npz.stem in found:
            problems.append(f"{npz}: stem {npz.stem} is in both layouts (also {found[npz.stem].source}); "
                            f"the npz is ignored")
            continue
        try:
            keys = _npz_keys(npz)
        except InputError as exc:
            problems.append(str(exc))
            continue
        wav = npz.with_suffix(".wav")
        found[npz.stem] = Bundle(npz.stem, label, split, wav if wav.is_file() else None, npz=npz, keys=keys)
    for wav in sorted(folder.rglob("*.wav")):
        if wav.stem not in found:
            problems.append(f"{wav}: audio without movement/SMPL-H features (no {wav.stem}.npz or per-key .npy)")
    bundles = []
    for stem, bundle in sorted(found.items()):
        if STEM.match(stem) is None:
            problems.append(f"{bundle.source}: stem {stem!r} is not V<vendor>_S<session>_I<interaction>_P<participant>")
        else:
            bundles.append(bundle)
    return bundles


def split_folders(root: Path, split: str | None) -> list[tuple[str, str, Path]]:
    """(label, split, folder) of ``split`` (``test``, or ``improvised/test`` for one label; None: every
    split) under ``root`` (the corpus root holding the label folders, or one label folder)."""
    root = Path(root)
    if not root.is_dir():
        raise InputError(root, "Seamless Interaction root folder not found")
    label_filter, _, split_name = (split or "").rpartition("/")
    if label_filter and label_filter not in LABELS:
        raise InputError(root, f"unknown label {label_filter!r} (expected {' or '.join(LABELS)})")
    if split_name and split_name not in SPLITS:
        raise InputError(root, f"unknown split {split_name!r} (expected one of {', '.join(SPLITS)}, optionally "
                               f"as <label>/<split>, e.g. improvised/test)")
    labels = [(root.name, root)] if root.name in LABELS else [(name, root / name) for name in LABELS]
    out = [(label, s, folder / s) for label, folder in labels for s in SPLITS
           if (folder / s).is_dir() and (not label_filter or label == label_filter) and (not split_name or s == split_name)]
    if not out:
        raise InputError(root, f"no <label>/<split> folder for {split or 'any split'} (labels {', '.join(LABELS)}; "
                               f"splits {', '.join(SPLITS)})")
    return out


def discover(root: Path, split: str | None) -> Discovery:
    """Every bundle of ``split`` under ``root`` (see :func:`split_folders`), grouped by dyad."""
    found = Discovery()
    for label, name, folder in split_folders(root, split):
        here: dict[str, list[Bundle]] = {}
        for bundle in _split_bundles(folder, label, name, found.problems):
            here.setdefault(bundle.dyad, []).append(bundle)
        for dyad, bundles in here.items():
            if dyad in found.bundles:
                found.problems.append(f"{bundles[0].source}: dyad {dyad} is also in {found.bundles[dyad][0].source} "
                                      f"(another label of the split); this copy is ignored")
            else:
                found.bundles[dyad] = bundles
    return found
