"""DualTalk split folders, read lazily: ``<clip>_speaker{1,2}.{wav,npz}`` in one flat folder per split.

``open_split(root, split)`` accepts the DualTalk root (holding ``train/``, ``test/``, ``ood/``) or a split
folder itself; a split folder given alone is the split named by the folder (``source.split`` is its
name and ``source.single_split`` is True), whatever split was asked for. Opening a split only lists
file names; a clip's files are read when it is loaded. Motion comes from the ground-truth ``.npz``
through :func:`dyadbench.datasets.dualtalk_files.load_gt_npz` (pose-half swap to [exp | jaw | head
rotation]); speech is 16 kHz mono (the release stores 32-bit float; 16-bit PCM is read too). Audio
may differ from the motion's duration by up to ``DURATION_TOLERANCE_S`` (the real release differs by
about one frame); it is then zero-padded or cut to exactly ``frames * 640`` samples. Larger
differences are errors naming the file.

Loaded clips carry ``meta["speaking"]``: per-participant speech activity from the documented energy VAD
(:mod:`dyadbench.features.activity`), since the release has no speech annotation.
"""

from __future__ import annotations

import re
import sys
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from tqdm import tqdm

from dyadbench.arrays import load_npz, nonfinite_count
from dyadbench.datasets.base import DEFAULT_SPLIT, ClipSource, DyadicClip, Participant
from dyadbench.datasets.dualtalk_files import EXP_DIM, GT_KEYS, POSE_DIM, load_gt_npz
from dyadbench.datasets.statistics import motion_statistics
from dyadbench.datasets.validation import ValidationReport
from dyadbench.datasets.wav import read_wav, require_format, wav_info
from dyadbench.errors import InputError
from dyadbench.features.activity import count_turns, energy_vad
from dyadbench.motion import FPS, SAMPLE_RATE

SPEAKERS = ("speaker1", "speaker2")
SPLITS = ("train", "test", "ood")
EXTENSIONS = ("wav", "npz")
FILE_PATTERN = re.compile(r"^(?P<clip>.+)_(?P<speaker>speaker[12])\.(?P<ext>wav|npz)$")
DURATION_TOLERANCE_S = 0.1
HOP = SAMPLE_RATE // int(FPS)
# per-frame shapes of every key of a released ground-truth npz (exp and pose are required)
NPZ_FRAME_SHAPES = {"exp": (EXP_DIM,), "pose": (POSE_DIM,), "shape": (100,), "tex": (50,), "cam": (3,),
                    "light": (9, 3)}


@dataclass
class ClipFiles:
    """The files of one dialogue found in a split folder."""

    clip: str
    folder: Path
    found: set[tuple[str, str]] = field(default_factory=set)  # (speaker, ext)

    def path(self, speaker: str, ext: str) -> Path:
        return self.folder / f"{self.clip}_{speaker}.{ext}"

    def missing(self) -> list[Path]:
        return [self.path(s, e) for s in SPEAKERS for e in EXTENSIONS if (s, e) not in self.found]


def scan_folder(folder: Path) -> dict[str, ClipFiles]:
    """Group the DualTalk files of a flat folder by dialogue (file names only; nothing is read)."""
    clips: dict[str, ClipFiles] = {}
    for entry in sorted(folder.iterdir()):
        match = FILE_PATTERN.match(entry.name)
        if match and entry.is_file():
            files = clips.setdefault(match["clip"], ClipFiles(match["clip"], folder))
            files.found.add((match["speaker"], match["ext"]))
    return clips


def _has_clip_files(folder: Path) -> bool:
    return folder.is_dir() and any(FILE_PATTERN.match(p.name) for p in folder.iterdir())


def split_folder(root: str | Path, split: str | None) -> Path:
    """``root/split`` when it exists, else ``root`` itself when it holds DualTalk files. ``split`` None:
    ``root`` when it holds DualTalk files, else ``root/test``."""
    root = Path(root)
    if not root.is_dir():
        raise InputError(root, "DualTalk folder not found")
    wanted = split or DEFAULT_SPLIT
    if (split is not None or not _has_clip_files(root)) and (root / wanted).is_dir():
        return root / wanted
    if _has_clip_files(root):
        return root
    raise InputError(root, f"expected a {wanted}/ sub-folder or <clip>_speaker1.wav/.npz and "
                           f"<clip>_speaker2.wav/.npz files")


def fit_audio(audio: np.ndarray, frames: int, wav_path: Path) -> np.ndarray:
    """Pad with zeros or cut ``audio`` to ``frames * HOP`` samples; error beyond the tolerance."""
    want = frames * HOP
    if abs(len(audio) - want) > DURATION_TOLERANCE_S * SAMPLE_RATE:
        raise InputError(wav_path, f"audio lasts {len(audio) / SAMPLE_RATE:.3f} s but the motion has {frames} "
                                   f"frames ({frames / FPS:.3f} s at {FPS:g} fps); "
                                   f"allowed difference {DURATION_TOLERANCE_S} s")
    if len(audio) >= want:
        return audio[:want]
    return np.concatenate([audio, np.zeros(want - len(audio), dtype=audio.dtype)])


class DualTalkSource(ClipSource):
    """One DualTalk split folder. Only dialogues with all four files are listed by :meth:`clip_ids`;
    the others are kept in :attr:`incomplete` (reported by :meth:`describe` and ``dyadbench data validate``)."""

    dataset = "dualtalk"

    def __init__(self, folder: Path, split: str):
        self.root = Path(folder)
        self.split = split
        scanned = scan_folder(self.root)
        self._files = {c: f for c, f in scanned.items() if not f.missing()}
        self.incomplete = {c: f.missing() for c, f in scanned.items() if f.missing()}
        if not self._files and not self.incomplete:
            raise InputError(self.root, "no DualTalk files (<clip>_speaker{1,2}.{wav,npz}) in this folder")

    def clip_ids(self) -> list[str]:
        return sorted(self._files)

    def identity(self, clip_id: str, speaker: str) -> str | None:
        """Persistent person id of a participant (the DualTalk release has none)."""
        return None

    def extra_meta(self, clip_id: str) -> dict:
        """Dataset-specific additions to a clip's ``meta`` (a ``speaking`` entry replaces the VAD's)."""
        return {}

    def _clip_files(self, clip_id: str) -> ClipFiles:
        files = self._files.get(clip_id)
        if files is None:
            if clip_id in self.incomplete:
                missing = ", ".join(p.name for p in self.incomplete[clip_id])
                raise InputError(self.root / clip_id, f"incomplete dialogue: missing {missing}")
            raise InputError(self.root, f"no dialogue {clip_id!r} in this folder")
        return files

    def participant_motions(self, clip_id: str) -> tuple[np.ndarray, ...]:
        """The speakers' motion as :meth:`load` gives it, from the ``.npz`` files only."""
        files = self._clip_files(clip_id)
        return tuple(load_gt_npz(files.path(speaker, "npz")).astype(np.float32) for speaker in SPEAKERS)

    def load(self, clip_id: str) -> DyadicClip:
        files = self._clip_files(clip_id)
        participants = []
        for speaker in SPEAKERS:
            motion = load_gt_npz(files.path(speaker, "npz")).astype(np.float32)
            wav = files.path(speaker, "wav")
            audio = fit_audio(read_wav(wav, sample_rate=SAMPLE_RATE), len(motion), wav)
            participants.append(Participant(speaker, motion, audio, self.identity(clip_id, speaker)))
        meta = {"folder": str(self.root), **self.extra_meta(clip_id)}
        if "speaking" not in meta:
            meta["speaking"] = {p.name: energy_vad(p.audio, SAMPLE_RATE, FPS) for p in participants}
            meta["speaking_source"] = "energy-vad"
        return DyadicClip(clip_id, tuple(participants), fps=FPS, sample_rate=SAMPLE_RATE, layout="flame56",
                          meta=meta)

    def describe(self) -> dict:
        info = super().describe()
        info["incomplete"] = {c: [p.name for p in m] for c, m in sorted(self.incomplete.items())}
        return info


def open_split(root: str | Path | None, split: str | None) -> DualTalkSource:
    """A lazily read DualTalk split: ``root/split`` (``root/test`` for None), or ``root`` itself when it is a
    split folder (then named by the folder; see the module docstring)."""
    if root is None:
        raise InputError(None, "the dualtalk dataset needs --data pointing at the DualTalk folder")
    folder = split_folder(root, split)
    single = folder == Path(root)
    source = DualTalkSource(folder, folder.resolve().name if single else split or DEFAULT_SPLIT)
    source.single_split = single
    if source.incomplete:
        names = sorted(p.name for m in source.incomplete.values() for p in m)
        shown = ", ".join(names[:3]) + (f" and {len(names) - 3} more" if len(names) > 3 else "")
        print(f"dyadbench: {source.root}: skipping {len(source.incomplete)} incomplete dialogue(s) "
              f"(missing {shown})", file=sys.stderr)
    return source


# --- validation ---------------------------------------------------------------------------------------

def _check_npz(path: Path, report: ValidationReport) -> int | None:
    """Check one ground-truth npz; return its frame count when exp/pose are usable."""
    try:
        arrays = load_npz(path)
    except InputError as exc:
        report.add(exc)
        return None
    missing = [k for k in GT_KEYS if k not in arrays]
    if missing:
        report.error(path, f"missing key(s) {', '.join(missing)} (has: {', '.join(sorted(arrays)) or 'none'})")
        return None
    exp = arrays["exp"]
    # the frame count comes from exp only when exp itself is (T, 50); otherwise only exp is blamed
    frames = exp.shape[0] if exp.shape[1:] == (EXP_DIM,) else None
    usable = frames is not None
    for key, tail in NPZ_FRAME_SHAPES.items():
        if key not in arrays:
            report.warn(path, f"no {key!r} array (the release has one; dyadbench does not need it)")
            continue
        a = arrays[key]
        if a.shape[1:] != tail or a.shape[0] != (frames if frames is not None else a.shape[0]):
            expected = "(" + ", ".join(map(str, (frames if frames is not None else "T", *tail))) + ")"
            transposed = a.ndim == 1 + len(tail) and a.shape[:len(tail)] == tail[::-1]
            report.error(path, f"{key} has shape {a.shape}, expected {expected}"
                               + ("; it looks transposed" if transposed else ""))
            usable &= key not in GT_KEYS
        elif a.dtype.kind != "f":
            report.error(path, f"{key} has dtype {a.dtype}, expected floating point")
            usable &= key not in GT_KEYS
        elif nonfinite_count(a):
            report.error(path, f"{key} contains {nonfinite_count(a)} NaN/inf values")
    if frames == 0:
        report.error(path, "exp has no frames")
        return None
    return frames if usable else None


def _check_wav(path: Path, report: ValidationReport) -> float | None:
    """Check one wav (16 kHz mono, readable; float samples finite); return its duration in seconds."""
    try:
        info = require_format(wav_info(path), SAMPLE_RATE)
        if info.encoding == "float":  # integer PCM cannot hold NaN/inf
            read_wav(path, sample_rate=SAMPLE_RATE)
    except InputError as exc:
        report.add(exc)
        return None
    return info.duration_s


def _validate_split(folder: Path, report: ValidationReport, progress: bool) -> None:
    clips = scan_folder(folder)
    if not clips:
        report.error(folder, "no DualTalk files (<clip>_speaker{1,2}.{wav,npz})")
        return
    for files in tqdm(clips.values(), desc=f"validate {folder.name}", unit="clip", disable=not progress):
        report.checked += 1
        for path in files.missing():
            kind = "motion (npz)" if path.suffix == ".npz" else "speech (wav)"
            report.error(path, f"missing: dialogue {files.clip} has no {kind} for this participant")
        frames = {}
        for speaker in SPEAKERS:
            npz_frames = _check_npz(files.path(speaker, "npz"), report) if (speaker, "npz") in files.found else None
            wav_s = _check_wav(files.path(speaker, "wav"), report) if (speaker, "wav") in files.found else None
            if npz_frames is not None:
                frames[speaker] = npz_frames
            if npz_frames is not None and wav_s is not None and abs(wav_s - npz_frames / FPS) > DURATION_TOLERANCE_S:
                report.error(files.path(speaker, "wav"),
                             f"audio lasts {wav_s:.3f} s but {files.path(speaker, 'npz').name} has {npz_frames} "
                             f"frames ({npz_frames / FPS:.3f} s); allowed difference {DURATION_TOLERANCE_S} s")
        if len(frames) == 2 and frames["speaker1"] != frames["speaker2"]:
            report.warn(folder / files.clip, f"speaker1 has {frames['speaker1']} frames, speaker2 "
                                             f"{frames['speaker2']}; clips are cut to the shorter")
    strays = [p.name for p in folder.iterdir() if p.suffix in (".wav", ".npz") and not FILE_PATTERN.match(p.name)]
    for name in sorted(strays):
        report.warn(folder / name, "not named <clip>_speaker1/2.wav/.npz; ignored")


def _split_folders(folder: Path) -> list[Path]:
    subs = [folder / s for s in SPLITS if _has_clip_files(folder / s)]
    return subs or [folder]


def validate_folder(folder: str | Path, progress: bool = True) -> ValidationReport:
    """Check a DualTalk split folder (or a root with train/ test/ ood/): complete speaker pairs, npz keys,
    shapes, dtypes and finite values, 16 kHz mono readable wavs, audio/motion duration agreement."""
    folder = Path(folder)
    report = ValidationReport(str(folder), "dualtalk")
    if not folder.is_dir():
        report.error(folder, "folder not found")
        return report
    for split in _split_folders(folder):
        _validate_split(split, report, progress)
    return report


# --- description --------------------------------------------------------------------------------------

def _clip_stats(files: ClipFiles) -> dict:
    """Frames, seconds, motion statistics, VAD talk fractions and turn count of one dialogue, from the
    files present."""
    motions = {s: load_gt_npz(files.path(s, "npz")) for s in SPEAKERS if (s, "npz") in files.found}
    audios = {s: read_wav(files.path(s, "wav"), sample_rate=SAMPLE_RATE) for s in SPEAKERS
              if (s, "wav") in files.found}
    if motions:
        frames = min(len(m) for m in motions.values())
    else:
        frames = int(min(len(a) for a in audios.values()) // HOP) if audios else 0
    out = {"frames": frames, "seconds": frames / FPS, "turns": None, "talk": [], "overlap": None,
           "motion": [motion_statistics(m, audios.get(s), SAMPLE_RATE, FPS) for s, m in motions.items()]}
    if len(audios) == 2:
        masks = [energy_vad(a, SAMPLE_RATE, FPS)[:frames] for a in audios.values()]
        n = min(len(m) for m in masks)
        masks = [m[:n] for m in masks]
        union = (masks[0] | masks[1]).sum()
        out.update(turns=count_turns(masks, FPS), talk=[float(m.mean()) for m in masks if n],
                   overlap=float((masks[0] & masks[1]).sum() / union) if union else 0.0)
    return out


def folder_info(folder: str | Path, progress: bool = True) -> dict:
    """Per split: dialogues (complete / incomplete), hours, frames, clip lengths; from the energy VAD
    the talk fraction per participant, overlap / union of talking and turn counts (see
    :mod:`dyadbench.features.activity`); the mean per-participant motion statistics of
    :mod:`dyadbench.datasets.statistics` (comparable with :mod:`dyadbench.synth.calibration`)."""
    folder = Path(folder)
    if not folder.is_dir():
        raise InputError(folder, "folder not found")
    info: dict = {"folder": str(folder), "layout": "dualtalk", "fps": FPS, "sample_rate": SAMPLE_RATE,
                  "turn_rule": "energy VAD; segments >= 1 s take the floor", "splits": {}}
    for split in _split_folders(folder):
        clips = scan_folder(split)
        if not clips:
            raise InputError(split, "no DualTalk files (<clip>_speaker{1,2}.{wav,npz})")
        stats = [_clip_stats(f) for f in tqdm(clips.values(), desc=f"info {split.name}", unit="clip",
                                              disable=not progress)]
        seconds = np.array([s["seconds"] for s in stats])
        turns = np.array([s["turns"] for s in stats if s["turns"] is not None], dtype=float)
        talk = [t for s in stats for t in s["talk"]]
        overlap = [s["overlap"] for s in stats if s["overlap"] is not None]
        motion = [m for s in stats for m in s["motion"]]
        info["splits"][split.name] = {
            "dialogues": len(clips),
            "complete": sum(1 for f in clips.values() if not f.missing()),
            "incomplete": sum(1 for f in clips.values() if f.missing()),
            "hours": float(seconds.sum() / 3600.0),
            "frames": int(sum(s["frames"] for s in stats)),
            "clip_seconds": {"mean": float(seconds.mean()), "min": float(seconds.min()),
                             "max": float(seconds.max())},
            "turns": {"total": int(turns.sum()), "mean": float(turns.mean()) if len(turns) else None,
                      "histogram": {k: int((turns == int(k)).sum()) for k in ("1", "2", "3")}
                      | {"4+": int((turns >= 4).sum()), "0": int((turns == 0).sum())}},
            "talk_fraction_mean": float(np.mean(talk)) if talk else None,
            "overlap_over_union_mean": float(np.mean(overlap)) if overlap else None,
            "motion_statistics_mean": {k: float(np.mean([m[k] for m in motion])) for k in motion[0]}
            if motion else None,
        }
    return info
