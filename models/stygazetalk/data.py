"""Gaze–head sessions as training material: valid segments, generator windows and style pairs.

A :class:`Segment` is a contiguous run of valid frames of one session (D3: frames with any
|angle| > ``angle_limit_deg`` are dropped and the session is cut there; segments too short for one
training window are discarded). Generator windows start on a fixed grid (D12) and carry window-local
audio features; style-encoder pairs are adjacent windows of one segment (D24).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from tqdm import tqdm

from dyadbench.datasets.base import ClipSource, DyadicClip
from dyadbench.errors import InputError
from models.stygazetalk.audio import HOP, window_audio
from models.stygazetalk.config import MOTION_DIM


@dataclass(frozen=True)
class Segment:
    """Valid frames [start, start + T) of one session: motion (T, 7) degrees, audio (T·640,) float32."""

    session: str
    speaker: str
    start: int
    motion: np.ndarray
    audio: np.ndarray

    @property
    def frames(self) -> int:
        return self.motion.shape[0]


def session_of(clip: DyadicClip) -> tuple[np.ndarray, np.ndarray, str]:
    """(motion (T,7), audio, speaker id) of a single-participant gaze–head clip."""
    if clip.layout != "gaze7" or len(clip.participants) != 1:
        raise InputError(clip.clip_id, f"StyGazeTalk reads single-participant gaze7 sessions, got layout "
                                       f"{clip.layout} with {len(clip.participants)} participants")
    p = clip.participants[0]
    motion = np.asarray(p.motion, dtype=np.float32)
    if not np.isfinite(motion).all():
        raise InputError(clip.clip_id, "motion has NaN or infinite values")
    return motion, np.asarray(p.audio, dtype=np.float32), p.identity or p.name


def segments_of(clip: DyadicClip, angle_limit_deg: float, min_frames: int) -> list[Segment]:
    """Valid segments of one session (D3)."""
    motion, audio, speaker = session_of(clip)
    valid = np.all(np.abs(motion) <= angle_limit_deg, axis=1)
    edges = np.flatnonzero(np.diff(np.concatenate([[0], valid.astype(np.int8), [0]])))
    out = []
    for lo, hi in zip(edges[0::2], edges[1::2]):
        if hi - lo >= min_frames:
            out.append(Segment(clip.clip_id, speaker, int(lo), motion[lo:hi],
                               window_audio(audio, int(lo), int(hi - lo))))
    return out


def load_segments(source: ClipSource, angle_limit_deg: float, min_frames: int) -> list[Segment]:
    segments = [s for clip in source for s in segments_of(clip, angle_limit_deg, min_frames)]
    if not segments:
        raise InputError(f"{source.dataset}/{source.split}",
                         f"no valid segment of at least {min_frames} frames (|angle| <= {angle_limit_deg})")
    return segments


def stacked_motion(segments: list[Segment]) -> np.ndarray:
    return np.concatenate([s.motion for s in segments]).reshape(-1, MOTION_DIM)


@dataclass
class WindowBank:
    """Generator training windows on a grid: motion (n, M+1+pre, 7) normalised, audio (n, M, F) normalised.

    Motion row j holds x_{u−1−pre}..x_{u+M−1} (pre = M when the style reads the preceding window, D7),
    audio row j the window-local features of frames u..u+M−1.
    """

    motion: np.ndarray
    audio: np.ndarray

    def __len__(self) -> int:
        return self.motion.shape[0]


def build_window_bank(segments: list[Segment], *, window: int, stride: int, pre: int, motion_norm,
                      audio_features, desc: str = "windows") -> WindowBank:
    """Every window start u on the grid u ≡ 0 (mod stride) with u ≥ 1 + pre and u + M ≤ T.

    ``motion_norm`` maps degrees to normalised units; ``audio_features(waveform)`` returns the normalised
    window-local features (M, F).
    """
    motions, audios = [], []
    starts = [(seg, u) for seg in segments
              for u in range(stride * -(-(1 + pre) // stride), seg.frames - window + 1, stride)]
    if not starts:
        raise InputError("segments", f"no window of {window} + {1 + pre} frames fits any segment")
    for seg, u in tqdm(starts, desc=desc, leave=False, disable=None):
        motions.append(motion_norm(seg.motion[u - 1 - pre:u + window]))
        audios.append(audio_features(seg.audio[u * HOP:(u + window) * HOP]))
    return WindowBank(np.stack(motions).astype(np.float32), np.stack(audios).astype(np.float32))


def sample_style_pairs(segments: list[Segment], rng: np.random.Generator, *, batch: int, window: int,
                       gap_max: int, min_anchor_gap: int, positives: str = "adjacent",
                       tries: int = 1000) -> tuple[list, list]:
    """B anchor windows a = X[s:s+M] and their positives b. Returns two lists of (segment index, start).

    ``positives="adjacent"`` (D24): b = X[s+M+g : s+2M+g] of the same segment, g ~ U{0..gap_max}.
    ``positives="same-speaker"`` (D48): b is a uniformly drawn window of the anchor's speaker, from any
    of the speaker's sessions, that does not overlap a (so that only what the speaker's windows share
    across time and sessions can match them). Anchors drawn from one session are at least
    ``min_anchor_gap`` frames apart.
    """
    if positives not in ("adjacent", "same-speaker"):
        raise InputError("positives", f"must be adjacent or same-speaker, got {positives!r}")
    span = 2 * window + gap_max
    usable = [i for i, s in enumerate(segments) if s.frames >= span]
    if not usable:
        raise InputError("segments", f"no segment has the {span} frames a style pair needs")
    weights = np.array([segments[i].frames - span + 1 for i in usable], dtype=np.float64)
    weights /= weights.sum()
    chosen: dict[str, list[int]] = {}
    a, b = [], []
    for _ in range(tries):
        if len(a) == batch:
            break
        i = int(usable[rng.choice(len(usable), p=weights)])
        seg = segments[i]
        s = int(rng.integers(0, seg.frames - span + 1))
        absolute = seg.start + s
        taken = chosen.setdefault(seg.session, [])
        if any(abs(absolute - other) < min_anchor_gap for other in taken):
            continue
        if positives == "adjacent":
            g = int(rng.integers(0, gap_max + 1))
            partner = (i, s + window + g)
        else:
            partner = _same_speaker_window(segments, i, s, window, rng)
            if partner is None:
                continue
        taken.append(absolute)
        a.append((i, s))
        b.append(partner)
    if len(a) < batch:
        raise InputError("segments", f"cannot draw {batch} anchors at least {min_anchor_gap} frames apart "
                                     f"within sessions; use more or longer sessions or a smaller batch")
    return a, b


def _same_speaker_window(segments: list[Segment], i: int, s: int, window: int,
                         rng: np.random.Generator) -> tuple[int, int] | None:
    """A uniform window start of the speaker of segment i that does not overlap X_i[s:s+M] (D48)."""
    speaker, anchor = segments[i].speaker, segments[i].start + s
    starts = []
    for j, seg in enumerate(segments):
        if seg.speaker != speaker or seg.frames < window:
            continue
        u = np.arange(seg.frames - window + 1)
        if seg.session == segments[i].session:
            u = u[np.abs(seg.start + u - anchor) >= window]
        starts.extend((j, int(k)) for k in u)
    return starts[int(rng.integers(len(starts)))] if starts else None
