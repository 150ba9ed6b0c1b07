"""Speech activity per motion frame (an energy VAD), speech segments, and turn counting.

Energy VAD (documented so that turn counts on real data can be reproduced):

1. frame level L_t = 20 log10(RMS of the samples of motion frame t + 1e-10) dBFS (hop = sr / fps);
2. floor = 10th percentile of L, peak = 95th percentile of L;
3. a frame is speech when L_t > max(floor + MIN_SNR_DB, floor + REL_THRESHOLD * (peak - floor));
4. gaps shorter than FILL_GAP_S between speech frames are filled, then speech runs shorter than
   MIN_SEGMENT_S are dropped.

A recording whose peak is less than MIN_SNR_DB above its floor has no speech.

Turns: the segments of both participants lasting at least MIN_TURN_S take the floor (shorter ones are
back-channels); ordered by start time, a new turn begins whenever the floor-taking speaker changes.
"""

from __future__ import annotations

import numpy as np

from dyadbench.features.logmel import rms_envelope

MIN_SNR_DB = 10.0
REL_THRESHOLD = 0.5
FILL_GAP_S = 0.3
MIN_SEGMENT_S = 0.12
MIN_TURN_S = 1.0


def frame_level_db(audio: np.ndarray, sample_rate: int = 16_000, fps: float = 25.0) -> np.ndarray:
    """(T,) RMS level of each motion frame's samples in dBFS."""
    return 20.0 * np.log10(rms_envelope(audio, sample_rate, fps) + 1e-10)


def runs(mask: np.ndarray) -> np.ndarray:
    """(K, 2) [start, stop) frame indices of the True runs of a boolean mask."""
    m = np.concatenate([[False], np.asarray(mask, dtype=bool), [False]])
    edges = np.flatnonzero(m[1:] != m[:-1])
    return edges.reshape(-1, 2)


def energy_vad(audio: np.ndarray, sample_rate: int = 16_000, fps: float = 25.0) -> np.ndarray:
    """(T,) bool speech activity per motion frame (see the module docstring for the rule)."""
    level = frame_level_db(audio, sample_rate, fps)
    if len(level) == 0:
        return np.zeros(0, dtype=bool)
    floor, peak = np.percentile(level, [10, 95])
    if peak - floor < MIN_SNR_DB:
        return np.zeros(len(level), dtype=bool)
    speech = level > max(floor + MIN_SNR_DB, floor + REL_THRESHOLD * (peak - floor))
    fill, shortest = int(round(FILL_GAP_S * fps)), int(round(MIN_SEGMENT_S * fps))
    for start, stop in runs(~speech):
        if 0 < start and stop < len(speech) and stop - start < fill:
            speech[start:stop] = True
    for start, stop in runs(speech):
        if stop - start < shortest:
            speech[start:stop] = False
    return speech


def segments_mask(segments: list[tuple[float, float]] | np.ndarray, n_frames: int, fps: float) -> np.ndarray:
    """(n_frames,) bool: frame centres (t + 0.5) / fps inside any [start, end) segment (seconds)."""
    centres = (np.arange(n_frames) + 0.5) / fps
    mask = np.zeros(n_frames, dtype=bool)
    for start, end in segments:
        mask |= (centres >= start) & (centres < end)
    return mask


def count_turns(masks: list[np.ndarray], fps: float) -> int:
    """Number of floor-holding turns in a conversation given each participant's (T,) activity."""
    floor = []
    for who, mask in enumerate(masks):
        for start, stop in runs(mask):
            if (stop - start) / fps >= MIN_TURN_S:
                floor.append((start, who))
    speakers = [who for _, who in sorted(floor)]
    return sum(1 for k, who in enumerate(speakers) if k == 0 or who != speakers[k - 1])
