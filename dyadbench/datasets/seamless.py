"""The Seamless Interaction corpus (Meta, 2025) as dyadic clips: motion layout, lazy reader, validation, info.

Files and pairing: :mod:`dyadbench.datasets.seamless_files` (both layouts, dyads = stems sharing ``V_S_I``).
``open_split(root, split)`` opens ``test`` (both labels) or ``improvised/test`` (one label); clip ids are
the dyads ``V<vendor>_S<session>_I<interaction>``, participants are named by their ``P<id>``, so a
prediction stem ``<clip>_<participant>`` is the corpus's own file stem.

**Motion layout** ``seamless`` (166 dims at 30 Hz; ``seamless-gaze`` 168 with the gaze encoding)::

    [ expression 128 | head rotation 3 | (gaze 2) | AU 24 | valence 1 | arousal 1 | emotion 8 | valid 1 ]

from the npz keys ``movement:expression``, ``movement:alignment_head_rotation``
(``movement:gaze_encodings``), ``movement:FAUValue``, ``movement:emotion_valence``,
``movement:emotion_arousal``, ``movement:emotion_scores`` and ``movement:is_valid``. The 34 emotion
dims (``emotion34``) are what the REACT-line metrics score.

**Invalid frames.** The corpus zero-fills the movement features of untracked frames (``is_valid`` = 0, whole
2-s blocks of 60 frames). What a model is handed for them, through the protocol's partner motion: the
last column (``valid``) is 0 and every feature column is exactly 0 (the few AU values the corpus leaves
at block edges are zeroed too), so a model can always tell them apart from real frames; the last column
of a prediction is ignored. The suite (:mod:`dyadbench.scoring.seamless`) never scores those frames.

**Skipped.** A bundle with no frames (an empty npz, header-only wav), a bundle without movement features
(vendors other than V00 ship none) and a dyad with fewer (or more) than two usable participants are left
out of the split; :attr:`SeamlessSource.skipped` lists each with its reason and file, and ``dyadbench data
validate`` / ``data info`` report them with counts.

**Speech**: 48 kHz 16-bit mono WAV, resampled to 16 kHz by :func:`dyadbench.datasets.seamless_audio.to_16k`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path

import numpy as np
from tqdm import tqdm

from dyadbench.datasets.base import DEFAULT_SPLIT, ClipSource, DyadicClip, Participant
from dyadbench.datasets.seamless_audio import SOURCE_RATE, TARGET_RATE, to_16k
from dyadbench.datasets.seamless_files import VALID_KEY, Bundle, discover, frames_of, split_folders
from dyadbench.datasets.validation import ValidationReport
from dyadbench.datasets.wav import read_wav
from dyadbench.errors import InputError
from dyadbench.motion import LAYOUTS, MotionLayout

FPS = 30.0
BLOCK_FRAMES = 60  # invalid movement comes in 2-s blocks starting at multiples of 60 frames
SENTINEL_ABS = 1000.0  # |smplh:translation| beyond this marks a frame whose box is invalid
#: (npz key, width) of each block of the layout, in order; GAZE only in ``seamless-gaze``
EXPRESSION = ("movement:expression", 128)
HEAD = ("movement:alignment_head_rotation", 3)
GAZE = ("movement:gaze_encodings", 2)
EMOTION = (("movement:FAUValue", 24), ("movement:emotion_valence", 1), ("movement:emotion_arousal", 1),
           ("movement:emotion_scores", 8))
VALID = (VALID_KEY, 1)
EMOTION_COLUMNS = ([f"AU{i}" for i in range(24)] + ["valence", "arousal"]
                   + ["anger", "contempt", "disgust", "fear", "happiness", "neutral", "sadness", "surprise"])


def _layout(name: str, gaze: bool) -> tuple[MotionLayout, tuple[tuple[str, int], ...]]:
    blocks = (EXPRESSION, HEAD) + ((GAZE,) if gaze else ()) + EMOTION + (VALID,)
    names = ("expression", "head") + (("gaze",) if gaze else ()) + ("au", "valence", "arousal", "emotion", "valid")
    bounds = np.cumsum([0] + [w for _, w in blocks])
    components = {n: slice(int(a), int(b)) for n, a, b in zip(names, bounds[:-1], bounds[1:])}
    components["emotion34"] = slice(components["au"].start, components["emotion"].stop)
    layout = MotionLayout(name=name, dim=int(bounds[-1]), components=components,
                          units="Seamless Interaction movement features (learned codes, head rotation, AU "
                                "intensities, valence/arousal, emotion scores) and a 0/1 validity column",
                          plausible_abs=100.0)
    return layout, blocks


SEAMLESS, BLOCKS = _layout("seamless", gaze=False)
SEAMLESS_GAZE, BLOCKS_GAZE = _layout("seamless-gaze", gaze=True)
for _l in (SEAMLESS, SEAMLESS_GAZE):
    LAYOUTS.setdefault(_l.name, _l)
MOVEMENT_KEYS = tuple(k for k, _ in BLOCKS_GAZE)


def valid_mask(motion: np.ndarray) -> np.ndarray:
    """(T,) bool: frames whose movement features are valid (the layout's last column is 1)."""
    return np.asarray(motion)[:, -1] > 0.5


def read_motion(bundle: Bundle, gaze: bool = False) -> np.ndarray:
    """(N, D) float32 in the ``seamless`` (``seamless-gaze``) layout; every column of an invalid frame is 0.

    Shapes are checked against (N, width) with one N for every key; errors name the file and key."""
    blocks = BLOCKS_GAZE if gaze else BLOCKS
    arrays = bundle.read([k for k, _ in blocks])
    frames = len(arrays[VALID_KEY])
    parts = []
    for key, width in blocks:
        a = np.asarray(arrays[key])
        if a.dtype.kind not in "fiub":
            raise InputError(bundle.source, f"{key} must be numeric, got dtype {a.dtype}")
        a = a.reshape(len(a), -1) if a.ndim >= 1 else a
        if a.shape != (frames, width):
            raise InputError(bundle.source, f"{key} has shape {arrays[key].shape}, expected ({frames}, {width}) "
                                            f"(N frames as {VALID_KEY})")
        parts.append(a.astype(np.float32))
    motion = np.concatenate(parts, axis=1)
    if not np.isfinite(motion).all():
        raise InputError(bundle.source, "movement features contain NaN or inf")
    valid = motion[:, -1] > 0.5
    motion[~valid] = 0.0
    motion[:, -1] = valid
    return motion


def read_audio(bundle: Bundle) -> np.ndarray:
    """Speech at 16 kHz (float32) from the 48 kHz WAV; empty when the bundle has no WAV."""
    if bundle.wav is None:
        return np.zeros(0, np.float32)
    return to_16k(read_wav(bundle.wav, sample_rate=SOURCE_RATE))


def bundle_problem(bundle: Bundle) -> str | None:
    """Why a participant bundle cannot be used (None: usable), naming the file."""
    if VALID_KEY not in bundle.keys:
        return f"{bundle.source}: no movement features (vendor {bundle.vendor} ships SMPL-H and keypoints only)"
    if frames_of(bundle) == 0:
        return f"{bundle.source}: empty bundle (0 frames)"
    return None


@dataclass
class SeamlessSplit:
    """The dyads of one split: usable pairs and what was skipped (each entry ``{dyad, reason}``)."""

    root: Path
    split: str
    pairs: dict[str, tuple[Bundle, Bundle]] = field(default_factory=dict)
    skipped: list[dict] = field(default_factory=list)

    @classmethod
    def open(cls, root: str | Path, split: str | None, progress: bool = False) -> "SeamlessSplit":
        found = discover(Path(root), split)
        out = cls(Path(root), split or "all")
        out.skipped = [{"dyad": None, "reason": p} for p in found.problems]
        for dyad, bundles in tqdm(sorted(found.bundles.items()), desc="seamless dyads", unit="dyad",
                                  disable=not progress, leave=False):
            problems = [bundle_problem(b) for b in bundles]
            usable = [b for b, p in zip(bundles, problems) if p is None]
            out.skipped += [{"dyad": dyad, "reason": p} for p in problems if p is not None]
            if len(usable) == 2:
                out.pairs[dyad] = (usable[0], usable[1])
            else:
                stems = ", ".join(b.stem for b in bundles)
                out.skipped.append({"dyad": dyad, "reason": f"{len(usable)} usable participant(s) of {len(bundles)} "
                                                           f"({stems}); a dyad needs exactly 2"})
        return out

    def skipped_dyads(self) -> int:
        return len({s["dyad"] for s in self.skipped if s["dyad"] is not None} - set(self.pairs))


class SeamlessSource(ClipSource):
    """A Seamless Interaction split, read dyad by dyad (see the module docstring)."""

    dataset = "seamless"
    suite = "seamless"

    def __init__(self, root: str | Path, split: str | None, gaze: bool = False):
        self.root = Path(root)
        self.split = split or DEFAULT_SPLIT
        self.gaze = gaze
        self.layout = SEAMLESS_GAZE if gaze else SEAMLESS
        if gaze:
            self.dataset = "seamless-gaze"

    @cached_property
    def data(self) -> SeamlessSplit:
        return SeamlessSplit.open(self.root, self.split)

    @property
    def skipped(self) -> list[dict]:
        return self.data.skipped

    def clip_ids(self) -> list[str]:
        return sorted(self.data.pairs)

    def _bundles(self, clip_id: str) -> tuple[Bundle, Bundle]:
        if clip_id not in self.data.pairs:
            raise InputError(self.root, f"no usable dyad {clip_id!r} in {self.split}")
        return self.data.pairs[clip_id]

    def participant(self, bundle: Bundle, audio: bool = True) -> Participant:
        """One participant's arrays, read now (audio only when asked for)."""
        return Participant(bundle.participant, read_motion(bundle, self.gaze),
                           read_audio(bundle) if audio else np.zeros(0, np.float32), identity=bundle.participant)

    def load(self, clip_id: str) -> DyadicClip:
        bundles = self._bundles(clip_id)
        participants = tuple(self.participant(b) for b in bundles)
        meta = {"label": bundles[0].label, "split": bundles[0].split, "stems": [b.stem for b in bundles],
                "invalid_frames": {p.name: int((~valid_mask(p.motion)).sum()) for p in participants},
                "invalid_frame_input": "feature columns 0 and valid column 0 (see dyadbench.datasets.seamless)"}
        return DyadicClip(clip_id, participants, fps=FPS, sample_rate=TARGET_RATE, layout=self.layout.name, meta=meta)

    def participant_motions(self, clip_id: str) -> tuple[np.ndarray, ...]:
        return tuple(read_motion(b, self.gaze) for b in self._bundles(clip_id))

    def describe(self) -> dict:
        return {**super().describe(), "skipped_dyads": self.data.skipped_dyads(), "skipped": list(self.skipped)}


def open_split(root: str | Path | None, split: str | None) -> SeamlessSource:
    """``--dataset seamless``: the dyads of ``split`` (``test`` or ``<label>/test``; None: test)."""
    if root is None:
        raise InputError(None, "the seamless dataset needs --data pointing at the Seamless Interaction root")
    return SeamlessSource(root, split)


def open_split_gaze(root: str | Path | None, split: str | None) -> SeamlessSource:
    """``--dataset seamless-gaze``: as :func:`open_split`, with the 2-d gaze encoding in the layout."""
    if root is None:
        raise InputError(None, "the seamless-gaze dataset needs --data pointing at the Seamless Interaction root")
    return SeamlessSource(root, split, gaze=True)


# --- validation and description (streaming: one bundle in memory at a time) ---------------------------

def _check_bundle(bundle: Bundle, report: ValidationReport) -> np.ndarray | None:
    """Read and check one usable bundle: motion, invalid blocks, SMPL-H sentinels, audio length."""
    try:
        motion = read_motion(bundle, GAZE[0] in bundle.keys)
    except InputError as exc:
        report.add(exc)
        return None
    invalid = ~valid_mask(motion)
    starts = np.flatnonzero(np.diff(np.concatenate([[0], invalid.astype(np.int8)])) == 1)
    off_grid = starts[starts % BLOCK_FRAMES != 0]
    if len(off_grid):
        report.warn(bundle.source, f"invalid movement run starting at frame {int(off_grid[0])}, not a multiple of "
                                   f"{BLOCK_FRAMES} ({len(off_grid)} such runs)")
    if invalid.all():
        report.warn(bundle.source, "every movement frame is invalid (nothing of this participant is scored)")
    if "smplh:translation" in bundle.keys:
        translation = bundle.read(["smplh:translation"])["smplh:translation"]
        sentinel = int((np.abs(translation).reshape(len(translation), -1) > SENTINEL_ABS).any(axis=1).sum())
        if sentinel:
            report.warn(bundle.source, f"{sentinel} frame(s) of smplh:translation hold sentinel values "
                                       f"(|x| > {SENTINEL_ABS:g}; not used by the motion layout)")
    if bundle.wav is None:
        report.warn(bundle.source, "no 48 kHz wav beside it")
    return motion


def validate_folder(folder: str | Path, progress: bool = True) -> ValidationReport:
    """Check every split under a Seamless root. Pairing problems, empty bundles, bundles without movement
    features and dyads without exactly two usable participants are warnings naming the file (the reader skips
    them; a count per split follows); each usable bundle's arrays must have the layout's shapes and finite
    values (errors); invalid runs off the 60-frame grid, all-invalid files and SMPL-H sentinels are warnings."""
    report = ValidationReport(str(folder), "seamless")
    try:
        splits = [SeamlessSplit.open(folder, name, progress=progress) for name in split_names(folder)]
    except InputError as exc:
        report.add(exc)
        return report
    for data in splits:
        for item in data.skipped:
            report.warn(item["dyad"] or "pairing", f"skipped: {item['reason']}")
        if data.skipped:
            report.warn(data.split, f"{data.skipped_dyads()} dyad(s) skipped, {len(data.pairs)} usable")
        for bundles in tqdm(data.pairs.values(), desc=f"validate {data.split}", unit="dyad", disable=not progress):
            for bundle in bundles:
                report.checked += 1
                _check_bundle(bundle, report)
    return report


def split_names(folder: str | Path) -> list[str]:
    """``<label>/<split>`` of every split folder under a Seamless root."""
    return [f"{label}/{split}" for label, split, _ in split_folders(Path(folder), None)]


@dataclass
class _Running:
    """Streaming per-column count, sum and sum of squares (float64) over valid frames."""

    count: int = 0
    total: np.ndarray | None = None
    squares: np.ndarray | None = None

    def add(self, frames: np.ndarray) -> None:
        x = frames.astype(np.float64)
        self.count += len(x)
        self.total = x.sum(axis=0) + (0 if self.total is None else self.total)
        self.squares = (x * x).sum(axis=0) + (0 if self.squares is None else self.squares)

    def component(self, cols: slice) -> dict:
        if not self.count:
            return {"frames": 0}
        mean = self.total[cols] / self.count
        var = np.maximum(self.squares[cols] / self.count - mean ** 2, 0.0)
        return {"mean": float(mean.mean()), "std": float(np.sqrt(var).mean()), "abs_max_mean": float(np.abs(mean).max())}


def folder_info(folder: str | Path, progress: bool = True) -> dict:
    """Hours, dyads, participants, vendors with and without movement features, invalid fraction and per-component
    statistics (mean over dims of the per-dim mean and std over valid frames), streaming over the files."""
    return {"folder": str(folder), "layout": "seamless", "fps": FPS,
            "audio": f"{SOURCE_RATE} Hz wav, read at {TARGET_RATE} Hz",
            "splits": {name: split_info(SeamlessSplit.open(folder, name, progress=progress), progress)
                       for name in split_names(folder)}}


def split_info(data: SeamlessSplit, progress: bool = True) -> dict:
    """:func:`folder_info` of one split."""
    vendors: dict[str, dict[str, int]] = {}
    no_movement = [s["reason"] for s in data.skipped if "no movement features" in s["reason"]]
    for item in data.skipped:
        if "no movement features" in item["reason"]:
            vendor = item["reason"].split("vendor ")[1].split(" ")[0]
            vendors.setdefault(vendor, {"with_movement": 0, "without_movement": 0})["without_movement"] += 1
    running, frames, invalid, people = _Running(), 0, 0, set()
    for bundles in tqdm(data.pairs.values(), desc=f"info {data.split}", unit="dyad", disable=not progress):
        for bundle in bundles:
            vendors.setdefault(bundle.vendor, {"with_movement": 0, "without_movement": 0})["with_movement"] += 1
            people.add(bundle.participant)
            motion = read_motion(bundle)
            valid = valid_mask(motion)
            frames += len(motion)
            invalid += int((~valid).sum())
            running.add(motion[valid])
    return {"dyads": len(data.pairs), "participants": len(people), "participant_files": 2 * len(data.pairs),
            "hours": frames / FPS / 3600, "frames": frames, "invalid_fraction": invalid / frames if frames else None,
            "vendors": dict(sorted(vendors.items())), "files_without_movement": len(no_movement),
            "skipped_dyads": data.skipped_dyads(), "skipped": [s["reason"] for s in data.skipped],
            "components": {name: running.component(cols) for name, cols in SEAMLESS.components.items()
                           if name != "valid"}}
