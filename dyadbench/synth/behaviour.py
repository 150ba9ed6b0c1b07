"""Face and head motion of one participant from its own speech and its partner's behaviour.

Every lag below is causal (the response comes after its cause) and given in frames at 25 fps; the
corpus docstring (:mod:`dyadbench.synth.corpus`) tabulates which signal drives which component.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from dyadbench.synth.signals import bump_kernel, causal_response, delay, lowpass, nod_kernel, ou_process
from dyadbench.synth.speech import SpeechSignals
from dyadbench.synth.styles import AFFECT_DIM, EXP_DIM, Style, World
from dyadbench.synth.timeline import Track

JAW_LAG = 2  # jaw opening <- own speech envelope (80 ms)
ARTIC_LAG = 1  # mouth articulation expression <- own envelope and vowel (40 ms)
HEAD_PROSODY_LAG = 3  # speaker head pitch <- own pitch contour (120 ms)
BEAT_LAG = 2  # speaker beat nod <- own emphasised syllable (80 ms)
MIRROR_LAG = 12  # expression affect <- partner's spontaneous affect (480 ms)
JAW_OPEN_VOWEL, JAW_VOWEL_SLOPE = 1.4, 1.0  # jaw drive = envelope x (1.4 - 1.0 x vowel spread)
JAW_SPEECH_NOISE = 0.25  # articulation noise while speaking, in units of jaw_gain
PITCH_NORM = 0.12  # relative pitch deviation mapped to one unit of head_speak_amp


@dataclass(frozen=True)
class Spontaneous:
    """A participant's own (non-mirrored) affect and listener nods, computed before mirroring."""

    affect: np.ndarray  # (T, AFFECT_DIM)
    listener_nod: np.ndarray  # (T,) rad on the head pitch axis
    responded_events: np.ndarray  # frames of partner events this participant responded to


def partner_events(partner: Track, fps: float) -> np.ndarray:
    """Frames of the partner's phrase ends and emphasised syllables (sorted, unique)."""
    times = np.concatenate([partner.phrase_ends("phrase"), partner.emphasis_times()])
    return np.unique(np.round(times * fps).astype(np.int64))


def spontaneous(r: np.random.Generator, style: Style, own: SpeechSignals, own_track: Track, partner_track: Track,
                fps: float) -> Spontaneous:
    """Idle affect, smiles and nods in response to partner events, brow raises on own emphasis."""
    n = len(own.speaking)
    events = partner_events(partner_track, fps)
    events = events[(events < n)]
    listening = events[~own.speaking[events]] if len(events) else events
    nod_at = listening[r.random(len(listening)) < style.nod_prob]
    smile_at = listening[r.random(len(listening)) < style.smile_prob]
    nod = style.nod_amp * causal_response(n, nod_at + int(round(style.nod_lag_s * fps)), nod_kernel(fps),
                                          r.uniform(0.7, 1.3, len(nod_at)))
    affect = ou_process(r, n, 1.5 * fps, style.affect_std * np.array([0.4, 0.4, 1.0, 1.0]), AFFECT_DIM)
    affect[:, 0] += style.smile_amp * causal_response(
        n, smile_at + int(round(style.smile_lag_s * fps)), bump_kernel(fps, 0.15, 0.6, 2.0),
        r.uniform(0.6, 1.2, len(smile_at)))
    own_emph = np.round(own_track.emphasis_times() * fps).astype(np.int64)
    affect[:, 1] += 0.8 * causal_response(n, own_emph, bump_kernel(fps, 0.05, 0.2, 0.6))
    return Spontaneous(affect=affect, listener_nod=nod, responded_events=np.union1d(nod_at, smile_at))


def motion(r: np.random.Generator, style: Style, w: World, own: SpeechSignals, own_track: Track,
           mine: Spontaneous, partners: Spontaneous, fps: float) -> np.ndarray:
    """(T, 56) float32 [exp 50 | jaw 3 | head rotation 3] of one participant."""
    n = len(own.speaking)
    env = delay(own.envelope, ARTIC_LAG)
    vow = delay(own.vowel, ARTIC_LAG)
    affect = mine.affect + style.mirror_gain * lowpass(delay(partners.affect, MIRROR_LAG), 3.0)
    blinks = np.flatnonzero(r.random(n) < style.blink_rate / fps)
    blink = causal_response(n, blinks, np.array([0.3, 0.9, 1.0, 0.6, 0.2]), r.uniform(0.8, 1.2, len(blinks)))
    exp = (np.asarray(style.exp_offset)[None, :]
           + affect @ w.affect
           + style.artic_gain * env[:, None] * ((1.0 - vow)[:, None] * w.artic[0] + vow[:, None] * w.artic[1])
           + blink[:, None] * w.blink[None, :]
           + ou_process(r, n, 0.6 * fps, style.idle_exp_std * w.dim_scale, EXP_DIM)
           + r.normal(0.0, 0.03, (n, EXP_DIM)) * w.dim_scale)

    # open vowels open the jaw more than spread ones: loudness alone explains only part of the jaw
    speaking_smooth = lowpass(own.speaking.astype(np.float64), 10.0)
    jaw_env = lowpass(delay(own.envelope * (JAW_OPEN_VOWEL - JAW_VOWEL_SLOPE * own.vowel), JAW_LAG), 1.0)
    jaw = np.stack([
        style.jaw_rest + style.jaw_gain * (jaw_env + JAW_SPEECH_NOISE * speaking_smooth
                                            * ou_process(r, n, 3.0, 1.0)[:, 0])
        + ou_process(r, n, 0.5 * fps, 0.006)[:, 0],
        0.25 * style.jaw_gain * jaw_env * (delay(own.vowel, JAW_LAG) - 0.5) + ou_process(r, n, 0.4 * fps, 0.008)[:, 0],
        ou_process(r, n, 0.4 * fps, 0.008)[:, 0],
    ], axis=1)

    prosody = lowpass(delay(own.pitch, HEAD_PROSODY_LAG), 5.0) / PITCH_NORM
    own_emph = np.round(own_track.emphasis_times() * fps).astype(np.int64) + BEAT_LAG
    beat = causal_response(n, own_emph, nod_kernel(fps, freq_hz=3.0, decay_s=0.15, length_s=0.5))
    idle = ou_process(r, n, 2.0 * fps, style.idle_head_std * np.array([1.0, 1.2, 0.6]), 3)
    sway = ou_process(r, n, 0.8 * fps, 0.7 * style.head_speak_amp)[:, 0] * speaking_smooth
    head = np.asarray(style.head_mean)[None, :] + idle
    head[:, 0] += style.head_speak_amp * (prosody + 0.5 * beat) + mine.listener_nod
    head[:, 1] += sway
    head[:, 2] += 0.3 * style.head_speak_amp * lowpass(delay(own.envelope, HEAD_PROSODY_LAG), 5.0)
    return np.concatenate([exp, jaw, head], axis=1).astype(np.float32)
