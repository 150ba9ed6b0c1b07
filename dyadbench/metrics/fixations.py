"""I-DT fixation detection on binocular gaze angles (Salvucci & Goldberg 2000), as StyGazeTalk's FixRatio uses it.

Input: gaze (T, 4) in degrees, columns ``[L_pitch, L_yaw, R_pitch, R_yaw]`` (the gaze part of the 7-angle
gaze–head layout). Every frame gets a label: :data:`FIXATION`, :data:`SACCADE`, or :data:`INVALID` (NaN or
masked frames, which no window may span and which neither count).

Dispersion of the frames ``[s, e)``:

.. math:: D = (\\max x - \\min x) + (\\max y - \\min y)

- ``eyes="pooled"`` (default, the paper's "yaw and pitch across both eyes"): x = the left **and** right
  yaw values of the window, y = the left and right pitch values.
- ``eyes="cyclopean"``: x, y = the mean of the two eyes' yaw / pitch first (much less sensitive to
  vergence and to eyes that disagree, so FixRatio rises; record which one was used).

Labelling (``include_breaking_sample=False``, Salvucci's description)::

    s = start of a run of valid frames
    while s + min_frames <= end of run:
        e = s + min_frames
        if D[s, e) <= threshold:
            while e < end and D[s, e + 1) <= threshold: e += 1    # running max / min: O(1) a step
            label [s, e) fixation; s = e                          # the frame that broke it is not included
        else:
            s += 1
    every other valid frame: saccade

``include_breaking_sample=True`` follows pymovements' I-DT: the window grows while D < threshold
(strict) and the frame that broke the threshold is counted in the fixation.
"""

from __future__ import annotations

import numpy as np

from dyadbench.errors import InputError

FIXATION, SACCADE, INVALID = 1, 0, -1
EYE_MODES = ("pooled", "cyclopean")

DISPERSION_THRESHOLD_DEG = 3.5
MIN_FIXATION_FRAMES = 3


def _axis_bounds(gaze: np.ndarray, eyes: str) -> tuple[np.ndarray, ...]:
    """Per-frame (x_min, x_max, y_min, y_max): yaw is x, pitch is y."""
    pitch, yaw = gaze[:, [0, 2]], gaze[:, [1, 3]]
    if eyes == "cyclopean":
        pitch = pitch.mean(axis=1, keepdims=True)
        yaw = yaw.mean(axis=1, keepdims=True)
    return yaw.min(axis=1), yaw.max(axis=1), pitch.min(axis=1), pitch.max(axis=1)


def _valid_runs(valid: np.ndarray) -> list[tuple[int, int]]:
    """[start, end) of every run of consecutive valid frames."""
    edges = np.diff(np.concatenate([[0], valid.astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(edges == 1).tolist(), np.flatnonzero(edges == -1).tolist()))


def _label_run(bounds: tuple[list[float], ...], start: int, end: int, labels: np.ndarray, threshold: float,
               min_frames: int, include_breaking_sample: bool) -> None:
    x_lo, x_hi, y_lo, y_hi = bounds
    s = start
    while s + min_frames <= end:
        e = s + min_frames
        xl, xh = min(x_lo[s:e]), max(x_hi[s:e])
        yl, yh = min(y_lo[s:e]), max(y_hi[s:e])
        if (xh - xl) + (yh - yl) > threshold:
            s += 1
            continue
        while e < end:
            nxl, nxh = min(xl, x_lo[e]), max(xh, x_hi[e])
            nyl, nyh = min(yl, y_lo[e]), max(yh, y_hi[e])
            dispersion = (nxh - nxl) + (nyh - nyl)
            if include_breaking_sample:
                if (xh - xl) + (yh - yl) >= threshold:
                    break
                e += 1
                xl, xh, yl, yh = nxl, nxh, nyl, nyh
            else:
                if dispersion > threshold:
                    break
                e += 1
                xl, xh, yl, yh = nxl, nxh, nyl, nyh
        labels[s:e] = FIXATION
        s = e


def idt_labels(gaze: np.ndarray, *, threshold_deg: float = DISPERSION_THRESHOLD_DEG,
               min_frames: int = MIN_FIXATION_FRAMES, eyes: str = "pooled",
               include_breaking_sample: bool = False, valid: np.ndarray | None = None,
               name: str = "gaze") -> np.ndarray:
    """Per-frame I-DT labels (T,) int8: 1 fixation, 0 saccade, -1 invalid (see the module docstring).

    ``gaze`` (T, 4) degrees ``[L_pitch, L_yaw, R_pitch, R_yaw]``; ``valid`` (T,) bool marks usable frames
    (frames with a NaN are invalid too); ``name`` names the array in errors.
    """
    gaze = np.asarray(gaze, dtype=np.float64)
    if gaze.ndim != 2 or gaze.shape[1] != 4:
        raise InputError(name, f"I-DT needs gaze angles (T, 4) [L_pitch, L_yaw, R_pitch, R_yaw], got {gaze.shape}")
    if eyes not in EYE_MODES:
        raise InputError(name, f"eyes must be one of {EYE_MODES}, got {eyes!r}")
    if min_frames < 1 or not threshold_deg >= 0:
        raise InputError(name, f"need min_frames >= 1 and threshold_deg >= 0, got {min_frames}, {threshold_deg}")
    usable = np.isfinite(gaze).all(axis=1)
    if valid is not None:
        valid = np.asarray(valid, dtype=bool)
        if valid.shape != usable.shape:
            raise InputError(name, f"valid mask has shape {valid.shape}, expected {usable.shape}")
        usable &= valid
    labels = np.full(len(gaze), SACCADE, dtype=np.int8)
    labels[~usable] = INVALID
    bounds = tuple(b.tolist() for b in _axis_bounds(np.where(usable[:, None], gaze, 0.0), eyes))
    for start, end in _valid_runs(usable):
        _label_run(bounds, start, end, labels, float(threshold_deg), int(min_frames), include_breaking_sample)
    return labels


def fixation_counts(labels: np.ndarray) -> tuple[int, int]:
    """(N_fixation, N_saccade) of a label array; invalid frames count in neither."""
    labels = np.asarray(labels)
    return int(np.sum(labels == FIXATION)), int(np.sum(labels == SACCADE))


def fixation_spans(labels: np.ndarray) -> list[tuple[int, int]]:
    """[start, end) frame spans of consecutive fixation labels (adjacent fixations merge into one span)."""
    return _valid_runs(np.asarray(labels) == FIXATION)
