"""REACT 2023/2024 layout: split csv, mirrored sample order, Emotion csv, 3D_FV npy, neighbour matrix.

::

    <root>/{train,val,test}.csv                    header ",speaker_path,listener_path", one row per dialogue
    <root>/neighbour_emotion_{val,test}.npy         (2M, 2M) appropriateness matrix, mirrored order
    <root>/<split>/Emotion/<rel>.csv                header line + 751 rows x 25 floats
    <root>/<split>/3D_FV_files/<rel>.npy            (1, 751, 58) or (751, 58): 52 exp + 3 rot + 3 trans
    <root>/<split>/Audio_files/<rel>.wav            optional (not read)
    <root>/<split>/Video_files/<rel>/1.png ...      optional (not read)

**Mirrored order.** A split csv with M rows gives N = 2M samples: sample k < M has speaker = column 1
and listener = column 2 of row k; sample k >= M has speaker = column 2 and listener = column 1 of row
k - M. The neighbour matrix and the prediction order use this sample order.

Emotion csv values are parsed exactly (``float_precision="round_trip"``) and held as float32 like the
official loader. The feature-level metrics need only the Emotion files (and the neighbour matrix);
3D_FV, audio and video are optional.

:func:`open_split` yields one clip per dialogue with participants ``speaker1`` (column 1) and
``speaker2`` (column 2) whose motion is the 25-d emotion features (layout ``react25``) at 25 fps; audio
is not loaded (empty arrays; the wav paths, when present, are in ``meta``).
"""

from __future__ import annotations

import csv
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path

import numpy as np
import pandas as pd
from tqdm import tqdm

from dyadbench.arrays import check_values, load_npy, require_file, shape_problem
from dyadbench.datasets.base import DEFAULT_SPLIT, ClipSource, DyadicClip, Participant
from dyadbench.datasets.validation import ValidationReport
from dyadbench.errors import InputError
from dyadbench.motion import LAYOUTS, MotionLayout

FPS = 25.0
SPLITS = ("train", "val", "test")
SCORED_SPLITS = ("val", "test")
CSV_HEADER = ("", "speaker_path", "listener_path")
CLIP_FRAMES = 751
EMOTION_DIM = 25
FV_DIM = 58
EMOTION_DIR, FV_DIR, AUDIO_DIR, VIDEO_DIR = "Emotion", "3D_FV_files", "Audio_files", "Video_files"
EMOTION_COLUMNS = ([f"AU{i}" for i in range(15)] + ["valence", "arousal"]
                   + ["neutral", "happy", "sad", "surprise", "fear", "disgust", "anger", "contempt"])

REACT25 = MotionLayout(
    name="react25",
    dim=EMOTION_DIM,
    components={"au": slice(0, 15), "va": slice(15, 17), "expression": slice(17, 25)},
    units="15 binary action units, valence and arousal, 8 expression probabilities",
    plausible_abs=10.0,  # every feature lies in [-1, 1] (AUs 0/1, valence/arousal, probabilities)
)
LAYOUTS.setdefault(REACT25.name, REACT25)


def neighbour_path(root: Path, split: str) -> Path:
    return Path(root) / f"neighbour_emotion_{split}.npy"


def read_split_csv(path: Path) -> list[tuple[str, str]]:
    """(speaker_path, listener_path) per row; the header must be ``,speaker_path,listener_path``."""
    if not path.is_file():
        raise InputError(path, "split csv not found")
    with path.open(newline="") as handle:
        rows = list(csv.reader(handle))
    if not rows or tuple(c.strip() for c in rows[0])[1:] != CSV_HEADER[1:]:
        raise InputError(path, f"expected the header ',speaker_path,listener_path', got {rows[0] if rows else 'nothing'}")
    pairs = []
    for line, row in enumerate(rows[1:], start=2):
        if not row:
            continue
        if len(row) != 3 or not row[1].strip() or not row[2].strip():
            raise InputError(path, f"line {line}: expected 'index,speaker_path,listener_path', got {row}")
        pairs.append((_strip_ext(row[1].strip()), _strip_ext(row[2].strip())))
    if not pairs:
        raise InputError(path, "no dialogues listed")
    return pairs


def _strip_ext(rel: str) -> str:
    rel = rel.replace("\\", "/").strip("/")
    for ext in (".csv", ".npy", ".wav", ".mp4"):
        if rel.endswith(ext):
            return rel[: -len(ext)]
    return rel


def mirrored(pairs: list[tuple[str, str]]) -> list[tuple[str, str]]:
    """The N = 2M (speaker, listener) samples in REACT's mirrored order."""
    return list(pairs) + [(listener, speaker) for speaker, listener in pairs]


def read_emotion(path: Path) -> np.ndarray:
    """(frames, 25) float32 from an Emotion csv (one header line); errors name the file.

    Values must be finite and within float32's range once rounded to it (the official loader's precision)."""
    require_file(path)
    try:
        table = pd.read_csv(path, header=0, float_precision="round_trip")
    except (ValueError, OSError, pd.errors.ParserError) as exc:
        raise InputError(path, f"unreadable csv ({exc})") from None
    if table.shape[1] != EMOTION_DIM:
        transposed = len(table) in (EMOTION_DIM - 1, EMOTION_DIM)  # a header line may have taken a row
        expected = f"{EMOTION_DIM} columns, one row per frame (T, {EMOTION_DIM})"
        raise InputError(path, shape_problem((len(table), table.shape[1]), expected, transposed))
    try:
        values = table.to_numpy(dtype=np.float64)
    except (ValueError, TypeError):
        raise InputError(path, "contains non-numeric values") from None
    if len(values) == 0:
        raise InputError(path, "has no frames")
    values = values.astype(np.float32)
    check_values(values, path)
    return values


def read_fv(path: Path) -> np.ndarray:
    """(frames, 58) float32 3DMM coefficients from ``(1, T, 58)`` or ``(T, 58)``."""
    array = load_npy(path)
    if array.ndim == 3 and array.shape[0] == 1:
        array = array[0]
    if array.ndim != 2 or array.shape[1] != FV_DIM:
        raise InputError(path, f"expected (1, T, {FV_DIM}) or (T, {FV_DIM}), got {array.shape}")
    return array.astype(np.float32)


@dataclass
class ReactSplit:
    """One split of a REACT root: its dialogues, samples (mirrored) and files."""

    root: Path
    split: str
    pairs: list[tuple[str, str]] = field(default_factory=list)

    @classmethod
    def open(cls, root: str | Path, split: str) -> "ReactSplit":
        root = Path(root)
        if split not in SPLITS:
            raise InputError(root, f"unknown REACT split {split!r} (expected one of {', '.join(SPLITS)})")
        if not root.is_dir():
            raise InputError(root, "REACT root folder not found")
        return cls(root, split, read_split_csv(root / f"{split}.csv"))

    @property
    def samples(self) -> list[tuple[str, str]]:
        return mirrored(self.pairs)

    def emotion_path(self, rel: str) -> Path:
        return self.root / self.split / EMOTION_DIR / f"{rel}.csv"

    def fv_path(self, rel: str) -> Path:
        return self.root / self.split / FV_DIR / f"{rel}.npy"

    def audio_path(self, rel: str) -> Path:
        return self.root / self.split / AUDIO_DIR / f"{rel}.wav"

    @cached_property
    def people(self) -> list[str]:
        """Every relative path of the split, each once (in first-appearance order)."""
        return list(dict.fromkeys(p for pair in self.pairs for p in pair))

    def emotions(self, frames: int | None = None, progress: bool = False) -> dict[str, np.ndarray]:
        """Emotion features of every person (each file read once), cut to ``frames`` when given."""
        out = {}
        for rel in tqdm(self.people, desc=f"read {self.split} emotion", unit="file", disable=not progress):
            values = read_emotion(self.emotion_path(rel))
            if frames is not None:
                if len(values) < frames:
                    raise InputError(self.emotion_path(rel), f"has {len(values)} frames, need {frames}")
                values = values[:frames]
            out[rel] = values
        return out

    def ground_truth(self, frames: int, progress: bool = False) -> tuple[np.ndarray, np.ndarray]:
        """(listener, speaker) emotion arrays (N, frames, 25) float32 in mirrored sample order."""
        em = self.emotions(frames, progress)
        samples = self.samples
        listener = np.stack([em[lst] for _, lst in samples])
        speaker = np.stack([em[spk] for spk, _ in samples])
        return listener, speaker

    def neighbours(self) -> np.ndarray:
        """The (N, N) appropriateness matrix of a val/test split; a row without a 1 is an error naming it."""
        path = neighbour_path(self.root, self.split)
        if self.split not in SCORED_SPLITS:
            raise InputError(path, f"REACT ships neighbour matrices for val and test only, not {self.split}")
        matrix = load_npy(path)
        n = 2 * len(self.pairs)
        if matrix.shape != (n, n):
            raise InputError(path, f"expected ({n}, {n}) for the {len(self.pairs)} dialogues of "
                                   f"{self.split}.csv (mirrored), got {matrix.shape}")
        empty = np.flatnonzero((matrix == 1).sum(axis=1) == 0)
        if len(empty):
            k = int(empty[0])
            speaker, listener = self.samples[k]
            raise InputError(path, f"{len(empty)} row(s) have no neighbour (no entry equal to 1); first: row {k} "
                                   f"(speaker {speaker}, listener {listener})")
        return matrix


class ReactSource(ClipSource):
    """A REACT split as dialogues: participants speaker1 (csv column 1) and speaker2 (column 2)."""

    dataset = "react"

    def __init__(self, split: ReactSplit):
        self.data = split
        self.root = split.root
        self.split = split.split
        self._ids = {f"{self.split}_{i:05d}": pair for i, pair in enumerate(split.pairs)}

    def clip_ids(self) -> list[str]:
        return sorted(self._ids)

    def load(self, clip_id: str) -> DyadicClip:
        if clip_id not in self._ids:
            raise InputError(self.root, f"no dialogue {clip_id!r} in {self.split}.csv")
        rels = self._ids[clip_id]
        motions = [read_emotion(self.data.emotion_path(rel)) for rel in rels]
        participants = tuple(Participant(name, motion, np.zeros(0, dtype=np.float32), identity=rel)
                             for name, motion, rel in zip(("speaker1", "speaker2"), motions, rels))
        audio = {name: str(self.data.audio_path(rel)) for name, rel in zip(("speaker1", "speaker2"), rels)
                 if self.data.audio_path(rel).is_file()}
        return DyadicClip(clip_id, participants, fps=FPS, layout=REACT25.name,
                          meta={"paths": dict(zip(("speaker1", "speaker2"), rels)), "audio_paths": audio})


def open_split(root: str | Path | None, split: str | None) -> ReactSource:
    """The dialogues of ``root/<split>.csv`` (split None: test), lazily read."""
    if root is None:
        raise InputError(None, "the react dataset needs --data pointing at the REACT root folder")
    return ReactSource(ReactSplit.open(root, split or DEFAULT_SPLIT))


# --- validation ---------------------------------------------------------------------------------------

def _present_splits(root: Path) -> list[str]:
    return [s for s in SPLITS if (root / f"{s}.csv").is_file()]


def _validate_split(data: ReactSplit, report: ValidationReport, progress: bool) -> None:
    frames = {}
    for rel in tqdm(data.people, desc=f"validate {data.split}", unit="file", disable=not progress):
        report.checked += 1
        try:
            em = read_emotion(data.emotion_path(rel))
        except InputError as exc:
            report.add(exc)
            continue
        frames[rel] = len(em)
        if len(em) != CLIP_FRAMES:
            report.warn(data.emotion_path(rel), f"has {len(em)} frames; REACT clips have {CLIP_FRAMES}")
        fv = data.fv_path(rel)
        if fv.is_file():
            try:
                coeffs = read_fv(fv)
                if len(coeffs) != len(em):
                    report.warn(fv, f"has {len(coeffs)} frames, the emotion csv {len(em)}")
            except InputError as exc:
                report.add(exc)
        else:
            report.warn(fv, "no 3D_FV file (not needed for the feature-level metrics)")
    if data.split in SCORED_SPLITS:
        try:
            data.neighbours()
        except InputError as exc:
            report.add(exc)


def validate_folder(folder: str | Path, progress: bool = True) -> ValidationReport:
    """Check a REACT root: split csvs, every listed Emotion csv (25 numeric finite columns, 751 frames),
    3D_FV shapes when present, and for val/test the neighbour matrix ((2M, 2M), a 1 in every row)."""
    root = Path(folder)
    report = ValidationReport(str(root), "react")
    if not root.is_dir():
        report.error(root, "folder not found")
        return report
    splits = _present_splits(root)
    if not splits:
        report.error(root, "no split csv (train.csv, val.csv, test.csv)")
    for split in splits:
        try:
            data = ReactSplit.open(root, split)
        except InputError as exc:
            report.add(exc)
            continue
        _validate_split(data, report, progress)
    return report


def folder_info(folder: str | Path, progress: bool = True) -> dict:
    """Per split: dialogues, samples (2M), frames per clip, source corpora, neighbours per row, and
    which optional modalities (3D_FV, audio, video) are present."""
    root = Path(folder)
    if not root.is_dir():
        raise InputError(root, "folder not found")
    splits = _present_splits(root)
    if not splits:
        raise InputError(root, "no split csv (train.csv, val.csv, test.csv)")
    info: dict = {"folder": str(root), "layout": "react", "fps": FPS, "splits": {}}
    for split in splits:
        data = ReactSplit.open(root, split)
        em = data.emotions(progress=progress)
        lengths = np.array([len(v) for v in em.values()])
        sources: dict[str, int] = {}
        for rel in data.people:
            sources[rel.split("/")[0]] = sources.get(rel.split("/")[0], 0) + 1
        entry = {"dialogues": len(data.pairs), "samples": 2 * len(data.pairs), "people_clips": len(data.people),
                 "frames": {"min": int(lengths.min()), "max": int(lengths.max())}, "sources": sources,
                 "fv_files": sum(data.fv_path(r).is_file() for r in data.people),
                 "audio_files": sum(data.audio_path(r).is_file() for r in data.people),
                 "video_folders": sum((root / split / VIDEO_DIR / r).is_dir() for r in data.people)}
        if split in SCORED_SPLITS and neighbour_path(root, split).is_file():
            counts = (data.neighbours() == 1).sum(axis=1)
            entry["neighbours_per_row"] = {"mean": float(counts.mean()), "min": int(counts.min()),
                                           "max": int(counts.max()),
                                           "density": float(counts.mean() / len(counts))}
        info["splits"][split] = entry
    return info
