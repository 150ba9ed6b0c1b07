"""Synthetic gaze–head sessions: one speaker's 7 angles (degrees, 25 fps) plus 16 kHz speech.

A HAGE-like generative model (no real gaze data is public). Each session is simulated at 100 Hz and
averaged over 4 samples to 25 fps, as HAGE's 100-Hz gaze was resampled, then tracker noise is added:

1. **Turns and prosody**: speaking U(2, 8) s / listening U(1, 4) s, starting to speak with p = 0.6.
   Phrases of 5–14 syllables, ~5 Hz, every third syllable stressed (the first of each phrase too),
   pauses U(0.2, 0.6) s. The audio comes from the corpus's speech synthesiser
   (:func:`dyadbench.synth.speech.speech_signals`) with a fixed voice per speaker.
2. **Gaze in space**: fixations (Gamma(2.5)-distributed durations, mean ``fix_mean``) with micro-drift;
   from the partner's face the next target is an aversion with probability ``p_avert_speaking`` /
   ``p_avert_listening`` (uniform direction, Gamma(4) amplitude of mean ``avert_amp`` capped at 35°,
   vertical ×0.6 and 2° down), otherwise a within-face point N(0, ``face_sd``²). While speaking, with
   probability ``sync`` a saccade due within 300 ms before a stressed syllable moves to 40 ms before it.
   Saccades follow the main sequence (21 ms + 2.2 ms/°, minimum-jerk profile): hundreds of °/s, far
   above the 30°/s saccade threshold.
3. **Head**: a critically damped pursuit (time constant ``head_tau``) of ``head_share`` × the gaze
   target (up to 2× for targets from 15° to 35°), plus slow Ornstein–Uhlenbeck drift (4 s, σ ``drift``)
   and a 0.36-s raised-cosine pitch dip of depth ``nod`` centred on every stressed syllable while
   speaking (so the head's speed minimum, a motion beat, falls on the speech onset).
4. **Eyes**: eye-in-head = gaze-in-space − 0.95 · head (VOR gain 0.95), ± ``vergence``/2 in yaw; blinks
   (rate ``blink``/s) as 4–10° downward pitch artefacts; tracker noise N(0, ``noise``²) common to both
   eyes plus 0.4·``noise`` per eye; single-frame glitches (probability ``glitch`` per frame) of N(0, 4°)
   pitch and 0.3× that in yaw; head sensor noise 0.05°. Angles are clipped to ±39° (the layout's ±40°
   filter would otherwise cut the session).

Styles are drawn once per speaker (8 speakers in train/val/test) and jittered ±10 % per session; the
``ood`` split has 2 other speakers drawn from ranges beyond the training ones. Everything is
deterministic from ``seed``.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, replace

import numpy as np
from scipy.ndimage import gaussian_filter1d

from dyadbench.datasets.base import DyadicClip, Participant
from dyadbench.errors import ConfigError
from dyadbench.motion import FPS, SAMPLE_RATE
from dyadbench.seeding import rng
from dyadbench.synth.signals import block_mean, lowpass, ou_process
from dyadbench.synth.speech import speech_signals
from dyadbench.synth.styles import Style, style_pool
from dyadbench.synth.timeline import Track

SIM_RATE = 100.0  # Hz; 4 simulation samples per 25-fps frame
SUBSAMPLE = int(SIM_RATE / FPS)
VOR_GAIN = 0.95
HEAD_SENSOR_NOISE = 0.05
GLITCH_SD = 4.0
ANGLE_LIMIT = 39.0
NOD_DURATION_S = 0.36
SPLITS = ("train", "val", "test", "ood")
SPEAKERS = tuple(f"spk{i}" for i in range(1, 9))
OOD_SPEAKERS = ("ood1", "ood2")
DEFAULT_DURATION_S = 45.0
DEFAULT_SESSIONS = {"train": 16, "val": 8, "test": 8, "ood": 4}
PARTICIPANT = "subject"


@dataclass(frozen=True)
class GazeStyle:
    """A speaker's gaze–head style (see the module docstring for what each parameter does)."""

    fix_mean: float  # s
    p_avert_speaking: float
    p_avert_listening: float
    avert_amp: float  # deg
    face_sd: float  # deg
    head_share: float
    head_tau: float  # s
    nod: float  # deg
    drift: float  # deg
    noise: float  # deg
    glitch: float  # per frame
    blink: float  # per s
    vergence: float  # deg
    sync: float = 0.7
    micro_drift: float = 0.15  # deg, fixational drift


# (low, high) of each style parameter; "ood" widens every range beyond the training one.
PRESETS: dict[str, dict[str, tuple[float, float]]] = {
    "hage-like": {"fix_mean": (0.22, 0.40), "p_avert_speaking": (0.30, 0.55), "p_avert_listening": (0.05, 0.15),
                  "avert_amp": (10.0, 22.0), "face_sd": (1.5, 3.0), "head_share": (0.15, 0.40),
                  "head_tau": (0.15, 0.35), "nod": (1.5, 3.5), "drift": (1.2, 2.8), "noise": (0.42, 0.82),
                  "glitch": (0.02, 0.06), "blink": (0.25, 0.45), "vergence": (0.0, 0.8)},
    "clean": {"fix_mean": (0.16, 0.28), "p_avert_speaking": (0.30, 0.55), "p_avert_listening": (0.05, 0.15),
              "avert_amp": (10.0, 22.0), "face_sd": (1.5, 3.0), "head_share": (0.15, 0.40),
              "head_tau": (0.15, 0.35), "nod": (1.5, 3.5), "drift": (1.2, 2.8), "noise": (0.15, 0.35),
              "glitch": (0.005, 0.02), "blink": (0.25, 0.45), "vergence": (0.0, 0.8)},
}


def speaker_style(speaker: str, *, seed: int, preset: str = "hage-like") -> GazeStyle:
    """The style of ``speaker``, drawn by Latin-hypercube sampling over the corpus's speakers.

    For the 8 regular speakers each parameter's range is cut into 8 equal strata; a seeded permutation
    gives every speaker one stratum per parameter and a uniform draw inside it, so every corpus covers
    every range evenly (the corpus-level statistics vary little with the seed). ``ood`` speakers draw
    from ranges beyond the preset's (30 % of the width, on a random side; above when 0 leaves no room below).
    """
    if preset not in PRESETS:
        raise ConfigError(f"unknown gaze preset {preset!r} (known: {', '.join(PRESETS)})")
    ranges = PRESETS[preset]
    values = {}
    if speaker in OOD_SPEAKERS:
        r = rng(seed, "gaze-style", preset, speaker)
        for name, (lo, hi) in ranges.items():
            width = hi - lo
            below = r.random() >= 0.5 and lo - 0.3 * width >= 0.0  # no room below 0: go above
            lo, hi = (lo - 0.3 * width, lo) if below else (hi, hi + 0.3 * width)
            values[name] = float(r.uniform(lo, hi))
        values["p_avert_speaking"] = min(values["p_avert_speaking"], 0.95)
        return GazeStyle(**values)
    if speaker not in SPEAKERS:
        raise ConfigError(f"unknown synthetic speaker {speaker!r}")
    slot, n = SPEAKERS.index(speaker), len(SPEAKERS)
    for name, (lo, hi) in ranges.items():
        r = rng(seed, "gaze-style", preset, name)
        stratum = r.permutation(n)[slot]
        u = (stratum + r.uniform(size=n)[slot]) / n
        values[name] = float(lo + u * (hi - lo))
    return GazeStyle(**values)


def _jitter(style: GazeStyle, r: np.random.Generator, amount: float = 0.10) -> GazeStyle:
    fields = {k: v * float(r.uniform(1 - amount, 1 + amount)) for k, v in asdict(style).items() if k != "sync"}
    return replace(style, **fields)


# --- turns, prosody and speech --------------------------------------------------------------------------

def _speech_plan(duration: float, r: np.random.Generator) -> tuple[list[tuple[float, float]], Track]:
    """Speaking turns [(start, end)] and the syllable plan (a :class:`Track`) of one session."""
    turns, phrases, syl = [], [], []  # syl: (onset, duration, stressed, phrase index)
    t, speaking = 0.0, r.random() < 0.6
    while t < duration:
        end = min(duration, t + (r.uniform(2.0, 8.0) if speaking else r.uniform(1.0, 4.0)))
        if speaking:
            turns.append((t, end))
            s = t + r.uniform(0.05, 0.3)
            while s < end - 0.2:
                first = len(syl)
                for k in range(int(r.integers(5, 15))):
                    dur = r.uniform(0.12, 0.18)
                    if s + dur > end:
                        break
                    syl.append((s, dur, k % 3 == 0, len(phrases)))
                    s += r.uniform(0.16, 0.24)
                if len(syl) > first:
                    phrases.append((syl[first][0], syl[-1][0] + syl[-1][1]))
                s += r.uniform(0.2, 0.6)
        t, speaking = end, not speaking
    arr = np.array(syl, dtype=np.float64).reshape(-1, 4)
    stressed = arr[:, 2].astype(bool)
    track = Track(phrases=np.array(phrases, dtype=np.float64).reshape(-1, 2), kinds=("phrase",) * len(phrases),
                  onset=arr[:, 0], dur=arr[:, 1], amp=np.where(stressed, 1.0, 0.35),
                  vowel=r.uniform(0.0, 1.0, len(arr)), emph=stressed, phrase_of=arr[:, 3].astype(np.int64))
    return turns, track


def speaker_voice(speaker: str, seed: int) -> Style:
    """The speaker's voice: a fixed member of the synthetic corpus's style pool (seen / unseen for ood)."""
    if speaker in OOD_SPEAKERS:
        return style_pool("unseen", seed)[OOD_SPEAKERS.index(speaker)]
    return style_pool("seen", seed)[SPEAKERS.index(speaker)]


def _in_turn(t: float, turns: list[tuple[float, float]]) -> bool:
    return any(a <= t < b for a, b in turns)


# --- gaze in space -------------------------------------------------------------------------------------

def _min_jerk(n: int) -> np.ndarray:
    tau = (np.arange(1, n + 1)) / n
    return 10 * tau ** 3 - 15 * tau ** 4 + 6 * tau ** 5


def _gaze_targets(n: int, style: GazeStyle, turns, stress_onsets: np.ndarray,
                  r: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Gaze-in-space (n, 2) [pitch, yaw] at SIM_RATE, and the piecewise-constant target it moves to."""
    gaze = np.zeros((n, 2))
    target = np.zeros((n, 2))
    pos = np.zeros(2)
    i = 0
    while i < n:
        fix_end = i / SIM_RATE + r.gamma(2.5, style.fix_mean / 2.5)
        at_face = np.hypot(*pos) < 5.0
        speaking = _in_turn(fix_end, turns)
        if speaking and r.random() < style.sync:
            nxt = stress_onsets[np.searchsorted(stress_onsets, fix_end):][:1]
            if len(nxt) and nxt[0] - fix_end <= 0.3:
                fix_end = max(i / SIM_RATE + 0.05, nxt[0] - 0.04)
        j = min(n, int(round(fix_end * SIM_RATE)))
        gaze[i:j] = pos
        target[i:j] = pos
        if j >= n:
            break
        p_avert = style.p_avert_speaking if speaking else style.p_avert_listening
        if at_face and r.random() < p_avert:
            amp = min(35.0, r.gamma(4.0, style.avert_amp / 4.0))
            phi = r.uniform(0, 2 * np.pi)
            new = np.array([0.6 * amp * np.sin(phi) - 2.0, amp * np.cos(phi)])
        else:
            new = r.normal(0.0, style.face_sd, size=2)
        amp = float(np.hypot(*(new - pos)))
        k = max(1, int(round((0.021 + 0.0022 * amp) * SIM_RATE)))
        k = min(k, n - j)
        gaze[j:j + k] = pos + (new - pos) * _min_jerk(k)[:, None]
        target[j:j + k] = new
        pos, i = new, j + k
    return gaze, target


def _raised_cosine_dips(n: int, centres_s: np.ndarray, width_s: float, depth: np.ndarray) -> np.ndarray:
    out = np.zeros(n)
    half = int(round(width_s / 2 * SIM_RATE))
    offsets = np.arange(-half, half + 1)
    shape = 0.5 * (1 + np.cos(np.pi * offsets / half))
    for c, d in zip(np.round(centres_s * SIM_RATE).astype(int), np.broadcast_to(depth, centres_s.shape)):
        idx = c + offsets
        keep = (idx >= 0) & (idx < n)
        out[idx[keep]] += d * shape[keep]
    return out


def simulate_motion(duration_s: float, style: GazeStyle, turns: list[tuple[float, float]], track: Track,
                    r: np.random.Generator) -> np.ndarray:
    """(T, 7) degrees at 25 fps, T = floor(duration_s · 25)."""
    frames = int(duration_s * FPS)
    n = frames * SUBSAMPLE
    stress = track.onset[track.emph]
    gaze, target = _gaze_targets(n, style, turns, stress, r)
    gaze = gaze + ou_process(r, n, 0.3 * SIM_RATE, style.micro_drift, dims=2)

    ecc = np.hypot(target[:, 0], target[:, 1])
    share = style.head_share * (1.0 + np.clip((ecc - 15.0) / 20.0, 0.0, 1.0))
    tau = style.head_tau * SIM_RATE  # critically damped pursuit = two cascaded one-pole lags
    head_py = lowpass(lowpass(share[:, None] * target, tau), tau)
    drift = gaussian_filter1d(ou_process(r, n, 4.0 * SIM_RATE, style.drift * np.array([0.7, 1.0, 0.4]), dims=3),
                              0.08 * SIM_RATE, axis=0)
    head = drift + np.concatenate([head_py, np.zeros((n, 1))], axis=1)
    head[:, 0] -= _raised_cosine_dips(n, stress, NOD_DURATION_S, np.full(len(stress), style.nod))

    eye = gaze - VOR_GAIN * head[:, :2]
    n_blinks = r.poisson(style.blink * duration_s)
    blink_at = r.uniform(0, duration_s, n_blinks)
    blinks = np.zeros(n)
    for c, w, d in zip(blink_at, r.uniform(0.10, 0.25, n_blinks), r.uniform(4.0, 10.0, n_blinks)):
        blinks += _raised_cosine_dips(n, np.array([c]), w, np.array([d]))
    eye[:, 0] -= blinks

    # average to 25 fps, then add the sensors' noise
    head25, eye25 = block_mean(head, SUBSAMPLE), block_mean(eye, SUBSAMPLE)
    half_v = 0.5 * style.vergence
    left = eye25 + np.array([0.0, half_v])
    right = eye25 - np.array([0.0, half_v])
    common = r.normal(0.0, style.noise, size=(frames, 2))
    left = left + common + r.normal(0.0, 0.4 * style.noise, size=(frames, 2))
    right = right + common + r.normal(0.0, 0.4 * style.noise, size=(frames, 2))
    glitch = r.random(frames) < style.glitch
    jump = r.normal(0.0, GLITCH_SD, size=(frames, 1)) * np.array([1.0, 0.3]) * glitch[:, None]
    left, right = left + jump, right + jump
    head25 = head25 + r.normal(0.0, HEAD_SENSOR_NOISE, size=head25.shape)
    motion = np.concatenate([head25, left, right], axis=1)
    return np.clip(motion, -ANGLE_LIMIT, ANGLE_LIMIT)


# --- sessions ------------------------------------------------------------------------------------------

def session_speaker(split: str, index: int) -> str:
    speakers = OOD_SPEAKERS if split == "ood" else SPEAKERS
    return speakers[index % len(speakers)]


def session_id(split: str, index: int) -> str:
    return f"{split}{index:03d}_{session_speaker(split, index)}"


def make_gaze_session(split: str, index: int, seed: int = 0, duration_s: float | None = None,
                      preset: str = "hage-like") -> DyadicClip:
    """Session ``index`` of ``split``: a single-participant gaze7 clip with speech and speaking mask."""
    if split not in SPLITS:
        raise ConfigError(f"unknown gaze split {split!r} (known: {', '.join(SPLITS)})")
    duration = float(DEFAULT_DURATION_S if duration_s is None else duration_s)
    if duration < 1.0:
        raise ConfigError(f"duration_s must be at least 1 s, got {duration}")
    speaker = session_speaker(split, index)
    r = rng(seed, "gaze-session", preset, split, index)
    style = _jitter(speaker_style(speaker, seed=seed, preset=preset), r)
    turns, track = _speech_plan(duration, r)
    motion = simulate_motion(duration, style, turns, track, r)
    speech = speech_signals(rng(seed, "gaze-audio", split, index), track, speaker_voice(speaker, seed),
                            len(motion), FPS, SAMPLE_RATE)
    clip_id = session_id(split, index)
    return DyadicClip(
        clip_id=clip_id,
        participants=(Participant(PARTICIPANT, motion.astype(np.float32), speech.audio, identity=speaker),),
        fps=FPS, sample_rate=SAMPLE_RATE, layout="gaze7",
        meta={"speaking": {PARTICIPANT: speech.speaking}, "speaker": speaker, "style": asdict(style),
              "seed": seed, "preset": preset, "generator": "dyadbench.synth.gaze"},
    )


def make_gaze_sessions(split: str, n: int | None = None, seed: int = 0, duration_s: float | None = None,
                       preset: str = "hage-like") -> list[DyadicClip]:
    """``n`` sessions of ``split`` in memory (default: the split's size in :data:`DEFAULT_SESSIONS`)."""
    n = DEFAULT_SESSIONS.get(split, 8) if n is None else n
    return [make_gaze_session(split, i, seed, duration_s, preset) for i in range(n)]
