"""Learning2Listen layout: per-host ``train/`` and ``test/`` folders of 64-frame windows at 30 fps.

::

    <root>/<host>/{train,test}/p{0,1}_list_faces_clean_deca.npy    (N, 64, 184) the person while listening
                               p{0,1}_speak_faces_clean_deca.npy   (N, 64, 184) the person while speaking
                               p{0,1}_speak_audio_clean_deca.npy   (N, 256, 128) mel of that person's speech
                               p{0,1}_speak_files_clean_deca.npy   (N, 64, 3) video name, unused, frame number

Only ``[..., :56]`` is motion, in L2L's order [exp 50 | head rotation 3 | jaw 3]; it is converted to
dyadbench's flame56 order [exp | jaw | rotation] with :func:`dyadbench.motion.l2l_to_flame56`.

**Pairing** (the host is the listener): listener = ``p{o}_list_faces``, speaker motion =
``p{1-o}_speak_faces``, speaker audio = ``p{1-o}_speak_audio``, with o = 1 for ``fallon`` and 0 for
every other host (:func:`listener_person`); window n of the listener array goes with window n of the
speaker arrays. ``<root>`` may also be a single host folder (holding ``train/`` and ``test/``).

:func:`open_split` yields one clip per window, ``<host>_<split>_<n:05d>``, with participants
``listener`` and ``speaker`` (flame56 motion at 30 fps, no waveform: the speaker's mel spectrogram is
its ``speech_features``, 4 rows × 128 bins per frame). Only the listener is generated (``agents``), and
``dyadbench eval`` scores it with the L2L-line suite; a listener prediction is named ``<clip>_listener``.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from pathlib import Path

import numpy as np
from tqdm import tqdm

from dyadbench.arrays import check_values, load_npy, require_float, shape_problem
from dyadbench.datasets.base import DEFAULT_SPLIT, ClipSource, DyadicClip, Participant
from dyadbench.datasets.validation import ValidationReport
from dyadbench.errors import InputError
from dyadbench.motion import l2l_to_flame56

FPS = 30.0
SPLITS = ("train", "test")
HOSTS = ("conan", "devi2", "fallon", "kimmel", "stephen", "trevor")
WINDOW = 64
FEATURE_DIM = 184
MOTION_DIM = 56
MEL_ROWS = 4 * WINDOW
MEL_BINS = 128
KINDS = ("list_faces", "speak_faces", "speak_audio", "speak_files")
AGENT = "listener"


def array_name(person: int, kind: str) -> str:
    return f"p{person}_{kind}_clean_deca.npy"


def listener_person(host: str) -> int:
    """o: the listening person's index; the host listens (p1 on fallon, p0 elsewhere)."""
    return 1 if host == "fallon" else 0


def _is_split_folder(folder: Path) -> bool:
    return folder.is_dir() and any((folder / array_name(p, "list_faces")).is_file() for p in (0, 1))


def host_folders(root: str | Path) -> dict[str, Path]:
    """host name -> host folder: sub-folders of ``root`` holding train/ or test/, or ``root`` itself."""
    root = Path(root)
    if not root.is_dir():
        raise InputError(root, "Learning2Listen folder not found")
    if any(_is_split_folder(root / s) for s in SPLITS):
        return {root.name: root}
    hosts = {d.name: d for d in sorted(root.iterdir()) if any(_is_split_folder(d / s) for s in SPLITS)}
    if not hosts:
        raise InputError(root, "no <host>/{train,test}/p0_list_faces_clean_deca.npy arrays here")
    return hosts


@dataclass
class HostSplit:
    """The paired arrays of one host's split folder (read on first use)."""

    host: str
    folder: Path

    @property
    def listener(self) -> int:
        return listener_person(self.host)

    def path(self, person: int, kind: str) -> Path:
        return self.folder / array_name(person, kind)

    def _read(self, person: int, kind: str, tail: tuple[int, ...]) -> np.ndarray:
        path = self.path(person, kind)
        array = load_npy(path)
        if array.ndim != 1 + len(tail) or array.shape[1:] != tail:
            expected = f"(N, {', '.join(map(str, tail))})"
            raise InputError(path, shape_problem(array.shape, expected, transposed=array.shape[1:] == tail[::-1]))
        if kind != "speak_files":
            require_float(array, path)
            check_values(array, path)
        return array

    @cached_property
    def listener_faces(self) -> np.ndarray:
        return self._read(self.listener, "list_faces", (WINDOW, FEATURE_DIM))

    @cached_property
    def speaker_faces(self) -> np.ndarray:
        return self._read(1 - self.listener, "speak_faces", (WINDOW, FEATURE_DIM))

    @cached_property
    def speaker_audio(self) -> np.ndarray:
        return self._read(1 - self.listener, "speak_audio", (MEL_ROWS, MEL_BINS))

    @cached_property
    def speaker_files(self) -> np.ndarray:
        return self._read(1 - self.listener, "speak_files", (WINDOW, 3))

    def motion_files(self) -> list[tuple[Path, np.ndarray]]:
        """(file, (N, 64, 184) array) of the listener's and the speaker's faces."""
        return [(self.path(self.listener, "list_faces"), self.listener_faces),
                (self.path(1 - self.listener, "speak_faces"), self.speaker_faces)]

    def count(self) -> int:
        """Number of paired windows; every paired array must agree."""
        counts = {self.path(self.listener, "list_faces"): len(self.listener_faces),
                  self.path(1 - self.listener, "speak_faces"): len(self.speaker_faces),
                  self.path(1 - self.listener, "speak_audio"): len(self.speaker_audio)}
        if len(set(counts.values())) != 1:
            shown = ", ".join(f"{p.name}: {n}" for p, n in counts.items())
            raise InputError(self.folder, f"paired arrays disagree on the number of windows ({shown})")
        return len(self.listener_faces)


def host_splits(root: str | Path, split: str) -> list[HostSplit]:
    if split not in SPLITS:
        raise InputError(root, f"Learning2Listen has splits {', '.join(SPLITS)}, not {split!r}")
    found = [HostSplit(h, f / split) for h, f in host_folders(root).items() if _is_split_folder(f / split)]
    if not found:
        raise InputError(root, f"no host has a {split}/ folder")
    return found


class L2LSource(ClipSource):
    """Windows of every host of one split, as two-participant clips (listener, speaker)."""

    dataset = "l2l"
    suite = "l2l"

    def __init__(self, root: Path, split: str):
        self.root = Path(root)
        self.split = split
        self.hosts = host_splits(root, split)
        self._index = {f"{hs.host}_{split}_{n:05d}": (hs, n) for hs in self.hosts for n in range(hs.count())}

    def clip_ids(self) -> list[str]:
        return sorted(self._index)

    def load(self, clip_id: str) -> DyadicClip:
        if clip_id not in self._index:
            raise InputError(self.root, f"no window {clip_id!r} in the {self.split} split")
        hs, n = self._index[clip_id]
        empty = np.zeros(0, dtype=np.float32)
        participants = (
            Participant(AGENT, l2l_to_flame56(hs.listener_faces[n]).astype(np.float32), empty, identity=hs.host),
            Participant("speaker", l2l_to_flame56(hs.speaker_faces[n]).astype(np.float32), empty,
                        speech_features=hs.speaker_audio[n].astype(np.float32)),
        )
        meta = {"host": hs.host, "window": n, "files": hs.speaker_files[n].astype(str).tolist()}
        return DyadicClip(clip_id, participants, fps=FPS, layout="flame56", meta=meta, agents=(AGENT,))


def open_split(root: str | Path | None, split: str | None) -> L2LSource:
    """All hosts' windows of ``split`` (train or test; None: test) under ``root``."""
    if root is None:
        raise InputError(None, "the l2l dataset needs --data pointing at the Learning2Listen folder")
    return L2LSource(Path(root), split or DEFAULT_SPLIT)


def ground_truth(root: str | Path, split: str) -> tuple[list[str], np.ndarray, np.ndarray]:
    """(prediction stems ``<clip>_listener``, listener (N, 64, 56), speaker (N, 64, 56)) in flame56."""
    return stack_ground_truth(host_splits(root, split), split)


def window_stems(host: str, split: str, n: int) -> list[str]:
    """Prediction stems ``<host>_<split>_<n:05d>_listener`` of a host split's ``n`` windows."""
    return [f"{host}_{split}_{i:05d}_{AGENT}" for i in range(n)]


def stack_ground_truth(hosts: list[HostSplit], split: str) -> tuple[list[str], np.ndarray, np.ndarray]:
    """:func:`ground_truth` of the given host splits."""
    stems, listener, speaker = [], [], []
    for hs in hosts:
        stems += window_stems(hs.host, split, hs.count())
        listener.append(l2l_to_flame56(hs.listener_faces).astype(np.float64))
        speaker.append(l2l_to_flame56(hs.speaker_faces).astype(np.float64))
    return stems, np.concatenate(listener), np.concatenate(speaker)


# --- validation and description -------------------------------------------------------------------------

def validate_folder(folder: str | Path, progress: bool = True) -> ValidationReport:
    """Check every host's train/ and test/: the eight arrays exist with (N, 64, 184), (N, 256, 128) and
    (N, 64, 3) shapes, float and finite values, and the paired arrays (listener of the host, speaker of
    the other person) agree on N."""
    folder = Path(folder)
    report = ValidationReport(str(folder), "l2l")
    try:
        hosts = host_folders(folder)
    except InputError as exc:
        report.add(exc)
        return report
    for host, host_dir in tqdm(hosts.items(), desc="validate l2l", unit="host", disable=not progress):
        for split in SPLITS:
            split_dir = host_dir / split
            if not split_dir.is_dir():
                report.warn(split_dir, "missing split folder")
                continue
            hs = HostSplit(host, split_dir)
            for path in (hs.path(p, k) for p in (0, 1) for k in KINDS):
                if not path.is_file():
                    report.error(path, "missing array")
            paired = [hs.path(hs.listener, "list_faces")] + [hs.path(1 - hs.listener, k) for k in KINDS[1:]]
            if not all(p.is_file() for p in paired):
                continue
            try:
                report.checked += hs.count()
                if len(hs.speaker_files) != hs.count():
                    report.error(paired[-1], "disagrees with the paired arrays on the number of windows")
            except InputError as exc:
                report.add(exc)
    return report


def folder_info(folder: str | Path, progress: bool = True) -> dict:
    """Per host and split: paired windows, the listening person (o), seconds of listener motion."""
    hosts = host_folders(folder)
    info: dict = {"folder": str(folder), "layout": "l2l", "fps": FPS, "window_frames": WINDOW, "hosts": {}}
    for host, host_dir in tqdm(hosts.items(), desc="info l2l", unit="host", disable=not progress):
        entry = {"listener_person": listener_person(host)}
        for split in SPLITS:
            if _is_split_folder(host_dir / split):
                n = HostSplit(host, host_dir / split).count()
                entry[split] = {"windows": n, "seconds": n * WINDOW / FPS}
        info["hosts"][host] = entry
    return info
