"""Beat alignment score (BAS, Li et al. 2021 / AIST++) between gaze–head motion beats and speech onsets.

- **Motion envelope** (per group): the head (3 angles) and each eye (2 angles) are one "part" each;
  env_t = sum over the group's parts of ‖x_t - x_{t-1}‖ (°/frame), for t = 1..T-1.
  ``all`` = head + both eyes, ``gaze`` = both eyes, ``head`` = head.
- **Motion beats**: strict local minima of the envelope over ±``order`` frames (``scipy.signal.argrelextrema``
  with ``np.less``; edge frames are never beats), ``order = round(order_s · fps)`` (AIST++: 1/6 s). A beat's
  frame is the later frame of its difference. Time = frame / fps.
- **Speech onsets**: onset strength = mean over 128 mel bands of the positive first difference of the
  dB log-mel spectrogram (2048-sample window, one column per motion frame, top_db 80), normalised to
  [0, 1], then librosa's ``peak_pick`` with ``onset_detect``'s defaults converted to one-frame hops
  (pre_max 0, post_max 1, pre_avg 2, post_avg 3, wait 0, delta 0.07). Time = column / fps.
- **Score** (direction ``m2a``, the AIST++ direction): mean over motion beats b of exp(-d_b² / (2σ²)),
  d_b = distance in seconds to the nearest speech onset; ``a2m`` (Bailando's direction) averages over
  onsets the distance to the nearest motion beat. σ = ``sigma_s`` = 0.05 s. NaN when either beat set
  is empty (``empty_policy="nan"``; the AIST++ code returns 0: ``"zero"``).

Chance level is high (≈ σ√(2π) / mean beat spacing ≈ 0.25 for 0.5-s spacing), so the suite always
reports the same score against shuffled speech and the difference.
"""

from __future__ import annotations

import numpy as np
from scipy.ndimage import maximum_filter1d, uniform_filter1d
from scipy.signal import argrelextrema

from dyadbench.errors import InputError
from dyadbench.features.logmel import logmel_frames

PARTS = {"head": (slice(0, 3),), "gaze": (slice(3, 5), slice(5, 7)),
         "all": (slice(0, 3), slice(3, 5), slice(5, 7))}
DIRECTIONS = ("m2a", "a2m")
EMPTY_POLICIES = ("nan", "zero")

ORDER_S = 1.0 / 6.0
SIGMA_S = 0.05
ONSET_N_MELS = 128
ONSET_WIN = 2048
ONSET_TOP_DB = 80.0
PEAK_PICK = {"pre_max": 0, "post_max": 1, "pre_avg": 2, "post_avg": 3, "wait": 0, "delta": 0.07}


def motion_envelope(motion: np.ndarray, group: str = "head") -> np.ndarray:
    """env_t = sum over the group's parts p of ‖x_{t,p} - x_{t-1,p}‖, t = 1..T-1: (T-1,) in °/frame."""
    if group not in PARTS:
        raise InputError(None, f"BAS group must be one of {tuple(PARTS)}, got {group!r}")
    v = np.diff(np.asarray(motion, dtype=np.float64), axis=0)
    return sum(np.linalg.norm(v[:, part], axis=1) for part in PARTS[group])


def motion_beats(motion: np.ndarray, group: str = "head", *, fps: float = 25.0, order_s: float = ORDER_S,
                 min_speed: float = 0.0) -> np.ndarray:
    """Times (s) of the strict local minima of :func:`motion_envelope` over ±round(order_s·fps) frames.

    ``min_speed`` (°/frame, default 0 = off) drops minima whose ±order neighbourhood never exceeds it, so
    numerical jitter in a near-static output does not create beats.
    """
    env = motion_envelope(motion, group)
    order = max(1, int(round(order_s * fps)))
    if len(env) < 3:
        return np.zeros(0)
    idx = argrelextrema(env, np.less, order=order)[0]
    if min_speed > 0 and len(idx):
        local_max = maximum_filter1d(env, size=2 * order + 1, mode="nearest")
        idx = idx[local_max[idx] >= min_speed]
    return (idx + 1) / fps


def onset_strength(audio: np.ndarray, sample_rate: int = 16_000, fps: float = 25.0) -> np.ndarray:
    """Spectral-flux onset envelope, one value per motion frame (frame 0 is 0).

    o_k = (1/M) sum_m max(0, S_{k,m} - S_{k-1,m}), S = 10 log10 of mel power (M = 128 bands, 2048-sample
    Hann window centred on frame k), floored at max(S) - 80 dB.
    """
    power_ln = logmel_frames(audio, sample_rate, fps, n_mels=ONSET_N_MELS, win_length=ONSET_WIN, fmin=0.0)
    if not len(power_ln):
        return np.zeros(0)
    db = power_ln.astype(np.float64) * (10.0 / np.log(10.0))
    db = np.maximum(db, db.max() - ONSET_TOP_DB)
    flux = np.maximum(0.0, np.diff(db, axis=0)).mean(axis=1)
    return np.concatenate([[0.0], flux])


def peak_pick(x: np.ndarray, *, pre_max: int, post_max: int, pre_avg: int, post_avg: int, delta: float,
              wait: int) -> np.ndarray:
    """Indices n with x[n] = max(x[n-pre_max : n+post_max]), x[n] >= mean(x[n-pre_avg : n+post_avg]) + delta,
    and more than ``wait`` samples after the previous pick (librosa.util.peak_pick semantics)."""
    x = np.asarray(x, dtype=np.float64)
    if not len(x):
        return np.zeros(0, dtype=int)
    mov_max = maximum_filter1d(x, pre_max + post_max, mode="constant", cval=x.min(),
                               origin=int(np.ceil(0.5 * (pre_max - post_max))))
    mov_avg = uniform_filter1d(x, pre_avg + post_avg, mode="nearest",
                               origin=int(np.ceil(0.5 * (pre_avg - post_avg))))
    detections = x * (x == mov_max)
    detections = detections * (detections >= mov_avg + delta)
    peaks, last = [], -np.inf
    for i in np.flatnonzero(detections):
        if i > last + wait:
            peaks.append(i)
            last = i
    return np.asarray(peaks, dtype=int)


def speech_onsets(audio: np.ndarray, sample_rate: int = 16_000, fps: float = 25.0, **peak_params) -> np.ndarray:
    """Times (s) of speech onsets: :func:`peak_pick` on the [0, 1]-normalised :func:`onset_strength`.

    ``peak_params`` override :data:`PEAK_PICK` (librosa ``onset_detect`` defaults at one-frame hops).
    """
    env = onset_strength(audio, sample_rate, fps)
    if not len(env) or env.max() - env.min() <= 0:
        return np.zeros(0)
    env = (env - env.min()) / (env.max() - env.min())
    return peak_pick(env, **{**PEAK_PICK, **peak_params}) / fps


def _nearest_distance(points: np.ndarray, targets: np.ndarray) -> np.ndarray:
    """Distance from every point to the nearest of the sorted ``targets`` (binary search)."""
    pos = np.searchsorted(targets, points)
    left = targets[np.clip(pos - 1, 0, len(targets) - 1)]
    right = targets[np.clip(pos, 0, len(targets) - 1)]
    return np.minimum(np.abs(points - left), np.abs(points - right))


def beat_alignment(motion_beats_s: np.ndarray, audio_beats_s: np.ndarray, *, sigma_s: float = SIGMA_S,
                   direction: str = "m2a", empty_policy: str = "nan") -> float:
    """BAS = (1/|B|) sum_{b in B} exp(-d(b, A)² / (2σ²)), d = distance (s) to the nearest element of A.

    ``m2a``: B = motion beats, A = speech onsets. ``a2m``: B = speech onsets, A = motion beats.
    In [0, 1]; 1 when every beat of B sits exactly on one of A. Empty B or A: NaN (``"nan"``) or 0.
    """
    if direction not in DIRECTIONS or empty_policy not in EMPTY_POLICIES:
        raise InputError(None, f"direction in {DIRECTIONS}, empty_policy in {EMPTY_POLICIES}; "
                               f"got {direction!r}, {empty_policy!r}")
    if not sigma_s > 0:
        raise InputError(None, f"sigma_s must be > 0, got {sigma_s}")
    m = np.sort(np.asarray(motion_beats_s, dtype=np.float64))
    a = np.sort(np.asarray(audio_beats_s, dtype=np.float64))
    points, targets = (m, a) if direction == "m2a" else (a, m)
    if not len(points) or not len(targets):
        return float("nan") if empty_policy == "nan" else 0.0
    d = _nearest_distance(points, targets)
    return float(np.mean(np.exp(-(d ** 2) / (2.0 * sigma_s ** 2))))


def empty_reason(n_motion_beats: int, n_audio_beats: int) -> str | None:
    """Why a BAS is undefined, or None when both beat sets are non-empty."""
    if n_motion_beats == 0 and n_audio_beats == 0:
        return "no motion beats and no speech onsets"
    if n_motion_beats == 0:
        return "no motion beats (motion has no strict speed minima)"
    if n_audio_beats == 0:
        return "no speech onsets"
    return None
