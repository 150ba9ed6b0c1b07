"""The dyadbench gaze–head session layout: its adapter and validator.

The synthetic sessions are written by :mod:`dyadbench.synth.gaze_writer` and served as the
'synthetic-gaze' dataset by :mod:`dyadbench.datasets.synthetic_gaze`.

On-disk layout (one speaker per session; HAGE-style recordings, or the synthetic generator's output)::

    <root>/
      splits.csv              # index: session,speaker,split  (one row per session)
      <split>/                # train, val, test, ood, ...
        <session>.npz         # motion (T, 7) float, degrees, 25 fps, order
                              #   [head_pitch, head_yaw, head_roll, L_pitch, L_yaw, R_pitch, R_yaw]
                              #   (yaw + = the subject's left, pitch + = up; eyes are eye-in-head);
                              # fps () float = 25; speaker () str;
                              # optional: speaking (T,) bool, valid (T,) bool (False = tracker loss)
        <session>.wav         # 16 kHz mono speech (integer PCM or float), T/25 s long (± 1 frame)

Reading a session (:func:`open_split`):

- Frames with any |angle| > ``angle_limit_deg`` (40°, HAGE's filter) or ``valid`` False are dropped
  (NaN/inf angles are allowed in ``valid`` False frames only; elsewhere they are an error naming the file);
  the session is cut at those frames into contiguous segments (never joined across a gap) and
  segments shorter than ``min_segment_frames`` (75 = 3 s) are discarded. A session with no dropped
  frame is one clip named ``<session>``; otherwise each kept segment is a clip ``<session>-f<first frame>``.
  Dropped frame counts are reported by :meth:`GazeSource.describe`.
- Each clip has one participant named ``subject`` whose ``identity`` is the speaker id, layout
  ``gaze7``; ``meta["speaking"]["subject"]`` is the speaking mask when the file has one.
- Audio is trimmed to T·640 samples (zero-padded when at most one frame short).
"""

from __future__ import annotations

import csv
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from dyadbench.arrays import check_motion, check_values, load_npz
from dyadbench.datasets.base import DEFAULT_SPLIT, ClipSource, DyadicClip, Participant, split_folder_mismatch
from dyadbench.datasets.validation import ValidationReport
from dyadbench.datasets.wav import read_wav
from dyadbench.errors import ConfigError, InputError
from dyadbench.motion import FPS, GAZE7, SAMPLE_RATE

INDEX = "splits.csv"
INDEX_COLUMNS = ("session", "speaker", "split")
PARTICIPANT = "subject"
ANGLE_LIMIT_DEG = 40.0
MIN_SEGMENT_FRAMES = 75


# --- files ---------------------------------------------------------------------------------------------

def read_index(root: Path) -> list[dict]:
    """Rows of ``<root>/splits.csv`` (session, speaker, split); InputError naming the file when malformed."""
    path = Path(root) / INDEX
    if not path.is_file():
        raise InputError(path, "index not found: a gaze-head root holds splits.csv (session,speaker,split)")
    with open(path, newline="", encoding="utf-8") as f:
        reader = csv.DictReader(f)
        if tuple(reader.fieldnames or ())[:3] != INDEX_COLUMNS:
            raise InputError(path, f"header must start with {','.join(INDEX_COLUMNS)}, got {reader.fieldnames}")
        rows = list(reader)
    for i, row in enumerate(rows, start=2):
        if not all(row.get(c) for c in INDEX_COLUMNS):
            raise InputError(f"{path}:{i}", f"empty field in row {row}")
    sessions = [r["session"] for r in rows]
    if len(set(sessions)) != len(sessions):
        raise InputError(path, "a session is listed twice")
    return rows


@dataclass(frozen=True)
class SessionFile:
    """One session as stored: motion (T, 7) degrees, speaker, optional masks, audio."""

    session: str
    motion: np.ndarray
    speaker: str
    fps: float
    speaking: np.ndarray | None
    valid: np.ndarray | None


def read_session(npz_path: Path) -> SessionFile:
    """Read and check ``<session>.npz``; every problem is an InputError naming the file and key.

    NaN/inf angles are allowed only in frames marked ``valid`` False (tracker loss)."""
    arrays = load_npz(npz_path)
    for key in ("motion", "fps", "speaker"):
        if key not in arrays:
            raise InputError(npz_path, f"missing key {key!r} (has: {', '.join(arrays)}); "
                                       f"a session needs motion (T,7) degrees, fps, speaker")
    motion = check_motion(arrays["motion"], f"{npz_path}[motion]", GAZE7.dim, finite=False)
    fps = arrays["fps"]
    if fps.shape != () or fps.dtype.kind not in "fiu" or float(fps) != FPS:
        raise InputError(f"{npz_path}[fps]", f"must be the scalar {FPS:g} (frames per second), got {fps!r}")
    speaker = arrays["speaker"]
    if speaker.shape != () or speaker.dtype.kind != "U" or not str(speaker):
        raise InputError(f"{npz_path}[speaker]", f"must be a non-empty string scalar, got {speaker!r}")
    masks = {}
    for key in ("speaking", "valid"):
        if key in arrays:
            m = arrays[key]
            if m.dtype != bool or m.shape != (len(motion),):
                raise InputError(f"{npz_path}[{key}]", f"must be bool ({len(motion)},), got {m.dtype} {m.shape}")
            masks[key] = m
    tracked = masks["valid"][:, None] if "valid" in masks else True
    try:
        check_values(np.where(tracked, motion, 0.0), f"{npz_path}[motion]")
    except InputError as exc:
        raise InputError(exc.source, f"{exc.problem}; mark frames of tracker loss valid=False") from None
    return SessionFile(npz_path.stem, motion, str(speaker), float(fps), masks.get("speaking"), masks.get("valid"))


def keep_mask(session: SessionFile, angle_limit_deg: float = ANGLE_LIMIT_DEG) -> np.ndarray:
    """Frames kept: finite, every |angle| <= ``angle_limit_deg``, and ``valid`` where given."""
    finite = np.isfinite(session.motion).all(axis=1)
    keep = finite & (np.abs(np.where(np.isfinite(session.motion), session.motion, 0.0)) <= angle_limit_deg).all(axis=1)
    return keep & session.valid if session.valid is not None else keep


def segments(keep: np.ndarray, min_frames: int = MIN_SEGMENT_FRAMES) -> list[tuple[int, int]]:
    """[start, end) runs of kept frames with at least ``min_frames`` frames."""
    edges = np.diff(np.concatenate([[0], keep.astype(np.int8), [0]]))
    runs = zip(np.flatnonzero(edges == 1).tolist(), np.flatnonzero(edges == -1).tolist())
    return [(a, b) for a, b in runs if b - a >= min_frames]


def fit_audio(audio: np.ndarray, frames: int, wav_path: Path, sample_rate: int = SAMPLE_RATE) -> np.ndarray:
    """Audio cut to ``frames`` motion frames; zero-padded when at most one frame short."""
    hop = int(round(sample_rate / FPS))
    need = frames * hop
    if len(audio) < need - hop:
        raise InputError(wav_path, f"audio is {len(audio) / sample_rate:.3f} s but the motion is "
                                   f"{frames / FPS:.3f} s ({frames} frames); they must match within one frame")
    return np.pad(audio, (0, max(0, need - len(audio))))[:need]


# --- adapter -------------------------------------------------------------------------------------------

def resolve_root(path: Path, split: str | None) -> tuple[Path, str]:
    """(root, split) from a corpus root (holding splits.csv; split None: test) or a split folder inside one
    (split None or the folder's name)."""
    path = Path(path)
    if (path / INDEX).is_file():
        return path, split or DEFAULT_SPLIT
    if (path.parent / INDEX).is_file() and path.is_dir():
        if split not in (None, path.name):
            raise split_folder_mismatch(path, path.name, split)
        return path.parent, path.name
    raise InputError(path, f"not a gaze-head root: no {INDEX} here or in the parent folder")


class GazeSource(ClipSource):
    """One split of a gaze–head root, read lazily (see the module docstring for the layout and rules)."""

    dataset = "gaze"

    def __init__(self, root: Path, split: str, *, angle_limit_deg: float = ANGLE_LIMIT_DEG,
                 min_segment_frames: int = MIN_SEGMENT_FRAMES):
        self.root, self.split = Path(root), split
        self.angle_limit_deg, self.min_segment_frames = angle_limit_deg, min_segment_frames
        rows = [r for r in read_index(self.root) if r["split"] == split]
        if not rows:
            known = sorted({r["split"] for r in read_index(self.root)})
            raise InputError(self.root / INDEX, f"no session in split {split!r} (splits: {', '.join(known)})")
        self._speakers = {r["session"]: r["speaker"] for r in rows}
        self._clips: dict[str, tuple[str, int, int]] | None = None
        self._sessions: dict[str, SessionFile] = {}
        self.dropped_frames = 0
        self.discarded_segments = 0

    def session_path(self, session: str) -> Path:
        """The ``.npz`` file of a session of this split."""
        return self.root / self.split / f"{session}.npz"

    def session(self, session: str) -> SessionFile:
        """A session of this split as stored (every frame, before the dropping rules), read once."""
        if session not in self._sessions:
            data = read_session(self.session_path(session))
            if data.speaker != self._speakers[session]:
                raise InputError(self.session_path(session), f"speaker {data.speaker!r} differs from {INDEX}'s "
                                                     f"{self._speakers[session]!r}")
            self._sessions[session] = data
        return self._sessions[session]

    def _segment_all(self) -> dict[str, tuple[str, int, int]]:
        if self._clips is None:
            clips = {}
            for session in sorted(self._speakers):
                data = self.session(session)
                keep = keep_mask(data, self.angle_limit_deg)
                kept = segments(keep, self.min_segment_frames)
                self.dropped_frames += int(len(keep) - keep.sum())
                self.discarded_segments += len(segments(keep, 1)) - len(kept)
                if kept == [(0, len(keep))]:
                    clips[session] = (session, 0, len(keep))
                else:
                    clips.update({f"{session}-f{a:06d}": (session, a, b) for a, b in kept})
            self._clips = clips
        return self._clips

    def clip_ids(self) -> list[str]:
        return sorted(self._segment_all())

    def load(self, clip_id: str) -> DyadicClip:
        try:
            session, a, b = self._segment_all()[clip_id]
        except KeyError:
            raise InputError(f"{self.root}/{self.split}", f"no clip {clip_id!r}") from None
        data = self.session(session)
        wav_path = self.root / self.split / f"{session}.wav"
        audio = read_wav(wav_path, sample_rate=SAMPLE_RATE)
        hop = int(round(SAMPLE_RATE / FPS))
        audio = fit_audio(audio, len(data.motion), wav_path)[a * hop:b * hop]
        meta = {"session": session, "speaker": data.speaker, "first_frame": a}
        if data.speaking is not None:
            meta["speaking"] = {PARTICIPANT: data.speaking[a:b]}
        motion = data.motion[a:b].astype(np.float32)
        return DyadicClip(clip_id, (Participant(PARTICIPANT, motion, audio, identity=data.speaker),),
                          fps=FPS, sample_rate=SAMPLE_RATE, layout=GAZE7.name, meta=meta)

    def describe(self) -> dict:
        info = super().describe()
        info.update(sessions=len(self._speakers), dropped_frames=self.dropped_frames,
                    discarded_segments=self.discarded_segments, angle_limit_deg=self.angle_limit_deg,
                    min_segment_frames=self.min_segment_frames)
        return info


def open_split(root: Path | None, split: str | None) -> GazeSource:
    """The ``split`` of a gaze–head root, or the split folder ``root`` (``single_split``; asked for None or
    its own name)."""
    if root is None:
        raise ConfigError("the gaze dataset reads a folder: pass its root (the folder holding splits.csv); "
                          "the embedded synthetic sessions are the 'synthetic-gaze' dataset")
    base, split = resolve_root(Path(root), split)
    source = GazeSource(base, split)
    source.single_split = base != Path(root)
    return source


# --- validation and description ------------------------------------------------------------------------

def validate_folder(folder: Path) -> ValidationReport:
    """Check a gaze–head root (or split folder): index, every session's npz and wav, lengths, ranges."""
    folder = Path(folder)
    report = ValidationReport(str(folder), "gaze")
    try:
        root, only_split = resolve_root(folder, None)
        rows = read_index(root)
    except InputError as exc:
        report.add(exc)
        return report
    if (folder / INDEX).is_file():
        only_split = None
    listed = set()
    for row in rows:
        if only_split and row["split"] != only_split:
            continue
        npz = root / row["split"] / f"{row['session']}.npz"
        listed.add(npz)
        report.checked += 1
        try:
            data = read_session(npz)
            if data.speaker != row["speaker"]:
                raise InputError(npz, f"speaker {data.speaker!r} differs from {INDEX}'s {row['speaker']!r}")
            wav = npz.with_suffix(".wav")
            audio = read_wav(wav, sample_rate=SAMPLE_RATE)
            fit_audio(audio, len(data.motion), wav)
            keep = keep_mask(data)
            if not keep.all():
                report.warn(npz, f"{int((~keep).sum())} of {len(keep)} frames will be dropped "
                                 f"(|angle| > {ANGLE_LIMIT_DEG:g}°, NaN or valid=False)")
            if not segments(keep):
                report.error(npz, f"no run of {MIN_SEGMENT_FRAMES} usable frames")
        except InputError as exc:
            report.add(exc)
    splits = {only_split} if only_split else {r["split"] for r in rows}
    for split in sorted(splits):
        for npz in sorted((root / split).glob("*.npz")):
            if npz not in listed:
                report.warn(npz, f"not listed in {root / INDEX}; it is ignored")
    return report


def folder_info(folder: Path) -> dict:
    """Per-split sessions, speakers, frames, hours and the angle ranges of a gaze–head root."""
    root, only_split = resolve_root(Path(folder), None)
    if (Path(folder) / INDEX).is_file():
        only_split = None
    info: dict = {"root": str(root), "layout": "gaze", "fps": FPS, "sample_rate": SAMPLE_RATE, "splits": {}}
    for row in read_index(root):
        if only_split and row["split"] != only_split:
            continue
        data = read_session(root / row["split"] / f"{row['session']}.npz")
        s = info["splits"].setdefault(row["split"], {"sessions": 0, "speakers": set(), "frames": 0,
                                                     "dropped_frames": 0, "abs_max_deg": 0.0})
        s["sessions"] += 1
        s["speakers"].add(row["speaker"])
        s["frames"] += len(data.motion)
        s["dropped_frames"] += int((~keep_mask(data)).sum())
        finite = data.motion[np.isfinite(data.motion).all(axis=1)]
        s["abs_max_deg"] = max(s["abs_max_deg"], float(np.abs(finite).max()) if len(finite) else 0.0)
    for s in info["splits"].values():
        s["speakers"] = sorted(s["speakers"])
        s["hours"] = s["frames"] / FPS / 3600.0
    return info
