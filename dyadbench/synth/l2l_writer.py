"""Write synthetic splits of the embedded corpus in the Learning2Listen layout (:mod:`dyadbench.datasets.l2l`).

``write_l2l_split(out, split="test", clips=None, seed=0, jobs=1)`` generates ``clips`` dialogues with
:func:`dyadbench.synth.corpus.make_clip` and writes ``out/synth/<split>/`` (host ``synth``, so person 0
is the listener, as for every host but fallon):

- the 25-fps motion of both participants is resampled to 30 fps (linear interpolation) and cut into
  64-frame windows every :data:`STRIDE` frames;
- a window goes to the pair (``p0_list_faces``, ``p1_speak_*``) when speaker2 talks in at least half
  of its frames and more than speaker1 (speaker1 = person 0 listens), and to (``p1_list_faces``,
  ``p0_speak_*``) in the opposite case; other windows are skipped;
- faces arrays are (N, 64, 184) float32 with the motion in ``[:56]`` in L2L order
  [exp | rotation | jaw] (:func:`dyadbench.motion.flame56_to_l2l`) and zeros in the other 128 dims;
- audio arrays are (N, 256, 128) float32: the talker's 128-band log-mel spectrogram
  (:func:`dyadbench.features.logmel.logmel_frames`, 10 ms hop) over the window, linearly resampled to
  4 rows per motion frame;
- files arrays are (N, 64, 3) strings: clip name, "" (unused), frame number at 30 fps.

Clip ``i`` depends only on (seed, split, i), so the files do not depend on ``jobs``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from dyadbench import atomic
from dyadbench.datasets.base import DyadicClip
from dyadbench.datasets.l2l import (FEATURE_DIM, FPS, MEL_BINS, MEL_ROWS, MOTION_DIM, SPLITS, WINDOW,
                                    array_name)
from dyadbench.errors import ConfigError
from dyadbench.features.logmel import logmel_frames
from dyadbench.motion import flame56_to_l2l
from dyadbench.synth.corpus import make_clip
from dyadbench.synth.generation import SUMMARY, clip_count, map_tasks, split_folder
from dyadbench.synth.styles import GENERATOR_VERSION

HOST = "synth"
STRIDE = 32
MEL_FPS = 100.0
MARKER = SUMMARY
SPLIT_SIZES = {"train": 120, "test": 40}


def resample(values: np.ndarray, fps_in: float, fps_out: float) -> np.ndarray:
    """Linear interpolation of (T, D) values from fps_in to fps_out over the same duration."""
    n_out = int(np.floor((len(values) - 1) * fps_out / fps_in)) + 1
    t_out = np.arange(n_out) / fps_out * fps_in
    return np.stack([np.interp(t_out, np.arange(len(values)), values[:, d]) for d in range(values.shape[1])], axis=1)


def window_mel(audio: np.ndarray, sample_rate: int, start: int) -> np.ndarray:
    """(256, 128) log-mel of the audio under 30-fps frames start..start+63, 4 rows per frame."""
    first = int(round(start / FPS * sample_rate))
    last = int(round((start + WINDOW) / FPS * sample_rate))
    segment = np.zeros(last - first, dtype=np.float32)
    piece = audio[first:last]
    segment[:len(piece)] = piece
    mel = logmel_frames(segment, sample_rate, MEL_FPS, n_mels=MEL_BINS).astype(np.float64)
    positions = np.linspace(0, len(mel) - 1, MEL_ROWS)
    return np.stack([np.interp(positions, np.arange(len(mel)), mel[:, b]) for b in range(MEL_BINS)],
                    axis=1).astype(np.float32)


def _faces(motion30: np.ndarray, start: int) -> np.ndarray:
    out = np.zeros((WINDOW, FEATURE_DIM), dtype=np.float32)
    out[:, :MOTION_DIM] = flame56_to_l2l(motion30[start:start + WINDOW])
    return out


def clip_windows(clip: DyadicClip) -> dict[int, list[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]]]:
    """listening person (0 or 1) -> [(listener faces, talker faces, talker mel, files)] of one clip."""
    motions = [resample(p.motion.astype(np.float64), clip.fps, FPS) for p in clip.participants]
    speaking = [resample(np.asarray(clip.meta["speaking"][p.name], dtype=np.float64)[:, None], clip.fps, FPS)[:, 0]
                for p in clip.participants]
    n = min(len(m) for m in motions)
    out: dict[int, list] = {0: [], 1: []}
    for start in range(0, n - WINDOW + 1, STRIDE):
        talk = [float(s[start:start + WINDOW].mean()) for s in speaking]
        for listener in (0, 1):
            talker = 1 - listener
            if talk[talker] >= 0.5 and talk[talker] > talk[listener]:
                files = np.array([[clip.clip_id, "", str(start + f)] for f in range(WINDOW)], dtype="<U48")
                out[listener].append((_faces(motions[listener], start), _faces(motions[talker], start),
                                      window_mel(clip.participants[talker].audio, clip.sample_rate, start), files))
    return out


def _one(args: tuple[str, int, int]) -> dict[int, list]:
    split, index, seed = args
    return clip_windows(make_clip(split, index, seed))


def write_l2l_split(out: str | Path, *, split: str = "test", clips: int | None = None, seed: int = 0,
                    jobs: int = 1, progress: bool = True, force: bool = False) -> dict:
    """Generate ``clips`` dialogues (default: the split's standard size) into ``out/synth/<split>/``, replaced
    whole when complete (:func:`dyadbench.synth.generation.split_folder`; ``force``: even when it holds
    files the generator did not write)."""
    if split not in SPLITS:
        raise ConfigError(f"Learning2Listen splits are {', '.join(SPLITS)}, got {split!r}")
    n = clip_count(clips, SPLIT_SIZES[split], jobs)
    folder = Path(out) / HOST / split
    with split_folder(folder, "l2l", force) as staging:
        results = map_tasks(_one, [(split, i, seed) for i in range(n)], jobs=jobs, desc=f"synth l2l/{split}",
                            progress=progress)
        counts = {}
        for listener in (0, 1):
            windows = [w for r in results for w in r[listener]]
            if not windows:
                raise ConfigError(f"no window where person {1 - listener} talks; generate more clips")
            talker = 1 - listener
            stacked = [np.stack([w[i] for w in windows]) for i in range(4)]
            for kind, array in zip(("list_faces", "speak_faces", "speak_audio", "speak_files"), stacked):
                atomic.save_npy(staging / array_name(listener if kind == "list_faces" else talker, kind), array)
            counts[f"p{listener}_listening"] = len(windows)
        summary = {"layout": "l2l", "generator": "dyadbench.synth", "version": GENERATOR_VERSION, "seed": seed,
                   "split": split, "host": HOST, "dialogues": n, "windows": counts, "fps": FPS, "stride": STRIDE,
                   "window_rule": "talker speaks in >= half the frames and more than the listener"}
        atomic.write_json(staging / MARKER, summary)
    return {**summary, "folder": str(folder)}
