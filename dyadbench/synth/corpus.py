"""The embedded synthetic dyadic-conversation corpus: clips generated in memory, deterministically.

Clip ``i`` of a split depends only on ``(seed, split, i)`` (and the generator version), so any subset is
stable: ``make_clips("test", 10)`` is the first ten clips of ``make_clips("test", 533)``. Each clip has
two participants ``speaker1`` / ``speaker2`` with (T, 56) float32 motion in the flame56 layout
[exp 50 | jaw 3 | head rotation 3] at 25 fps and 16 kHz float32 mono speech (on the 16-bit PCM grid).

Conversation (:mod:`~dyadbench.synth.timeline`): floor-holding turns alternate (gamma lengths; the next
turn starts after a normal gap that is negative - an overlap - about half the time), each turn is a run
of phrases separated by short pauses; listeners add back-channels 150-450 ms after a partner's phrase end
and occasional interjections during partner speech. Speech (:mod:`~dyadbench.synth.speech`): syllables at
4-6 Hz with sin^2 envelopes, a harmonic voice with a declining pitch contour and pitch accents on
emphasised syllables, near-silence (-60 dBFS) between phrases.

What drives what (lags in frames at 25 fps; all causal; styles are per person, see
:mod:`~dyadbench.synth.styles`)::

    component              driven by                                     lag            gain (style)
    jaw opening (jaw 0)    own speech envelope x (1.4 - vowel spread),    2 (80 ms)      jaw_gain ~0.07-0.15 rad
                           1-frame low-pass; + noise while speaking       -              0.25 jaw_gain
    jaw lateral (jaw 1)    own envelope x (vowel spread - 0.5)            2              0.25 jaw_gain
    exp articulation       own envelope x vowel mix of 2 mouth bases      1 (40 ms)      artic_gain
    exp brow raise         own emphasised syllables (bump, ~0.2 s)        0              0.8
    exp smile              partner phrase ends + emphases, while the      smile_lag_s    smile_amp, prob
                           participant is silent (bump, decay 0.6 s)      0.4-0.75 s     smile_prob
    exp mirroring          partner's spontaneous affect (idle + smiles +  12 (480 ms)    mirror_gain 0.35-0.75
                           brow), 3-frame low-pass
    head pitch (rot 0)     own relative pitch contour / 0.12, low-pass    3 (120 ms)     head_speak_amp
                           own emphasised syllables (beat nod)            2              0.5 head_speak_amp
                           partner phrase ends + emphases, while silent   nod_lag_s      nod_amp, nod_prob
                           (damped 2.5 Hz nod)                            0.25-0.55 s
    head yaw (rot 1)       sway while speaking (OU, tau 0.8 s)            -              0.7 head_speak_amp
    head roll (rot 2)      own envelope, low-pass                         3              0.3 head_speak_amp
    everything             idle OU drift (exp tau 0.6 s, affect 1.5 s, head 2 s), blinks, tracker noise

Identity: a per-person expression offset (population mean + N(0, 0.3) x per-dim scale) and head mean
(N(0, [0.03, 0.04, 0.02]) rad around [0.1, 0.12, 0]) are constant over a person's clips; they are not
inferable from speech, so they set the floor of every model's MSE.

Measured (tests/test_synth_structure.py, 10 train clips, seed 5): jaw opening vs own speech RMS
envelope r = 0.73 at +2 frames (0.24 at lag 0); the listener's z-scored head-pitch speed averaged around
the partner's speech offsets (energy VAD) peaks +9 frames after them at 0.86 SD (at most 0.10 before
the offset); the listener's smile mode peaks at +19 frames (0.66 SD; 0.06 at the offset). Statistics
sit within a factor 3 of the two real DualTalk clips of :mod:`~dyadbench.synth.calibration` (e.g. exp
per-dim std 0.45, head std 0.021 rad, jaw opening 0.043 +- 0.028 rad; ood is livelier: 0.60, 0.032,
0.072 +- 0.037).

Consequences downstream: own speech predicts jaw, articulation, head prosody and brow raises; the
partner's speech predicts nods and smiles after its phrase ends; the partner's motion predicts mirrored
affect (checked by tests/test_synth_learnable.py). On 2 x 20 test clips, MSE exp / jaw / pose (raw)
of mean-frame (train mean) is 0.365 / 4.3e-4 / 1.68e-3; copying the partner (mime) is worse on MSE,
0.467 / 1.0e-3 / 2.4e-3, but has realistic variance and diversity (mean-frame has none); the partner
lagged by 12 frames (lagged mirror) is closer than mime on exp (0.439); a causal ridge regression on
own and partner speech features and partner expression (60 train clips) reaches 0.262 / 2.2e-4 /
1.64e-3. Idle drift and the identity offsets are unpredictable by design, so pose gains are small for
any model.

Splits: ``train``, ``test`` (and ``val``) draw people from the *seen* style pool; ``ood`` draws from the
*unseen* pool and uses different turn statistics (shorter turns and phrases, more overlap, more
back-channels). Clip lengths are log-normal with mean 31 s (clipped to 12-62 s).
"""

from __future__ import annotations

import numpy as np

from dyadbench.datasets.base import DyadicClip, Participant
from dyadbench.errors import ConfigError
from dyadbench.motion import FPS, SAMPLE_RATE
from dyadbench.seeding import rng as seeded_rng
from dyadbench.synth import behaviour
from dyadbench.synth.speech import speech_signals
from dyadbench.synth.styles import GENERATOR_VERSION, SPLIT_STATS, split_pool, style_pool, world
from dyadbench.synth.timeline import make_timeline

PARTICIPANTS = ("speaker1", "speaker2")
MIN_DURATION_S, MAX_DURATION_S = 12.0, 62.0


def clip_name(split: str, index: int) -> str:
    return f"synth_{split}_{index:05d}"


def _duration(r: np.random.Generator, mean: float) -> float:
    sigma = 0.3
    return float(np.clip(r.lognormal(np.log(mean) - sigma ** 2 / 2, sigma), MIN_DURATION_S, MAX_DURATION_S))


def make_clip(split: str, index: int, seed: int = 0, duration_s: float | None = None) -> DyadicClip:
    """Clip ``index`` of ``split`` (deterministic in seed, split, index and the generator version)."""
    pool_name = split_pool(split)
    stats = SPLIT_STATS[pool_name]
    pool = style_pool(pool_name, seed)
    r = seeded_rng(seed, split, index, "clip", GENERATOR_VERSION)
    a, b = r.choice(len(pool), size=2, replace=False)
    styles = (pool[a], pool[b])
    duration = _duration(r, stats.duration_mean_s) if duration_s is None else float(duration_s)
    n_frames = int(round(duration * FPS))
    if n_frames < 1:
        raise ConfigError(f"clip duration must be at least one frame, got {duration_s} s")
    duration = n_frames / FPS
    timeline = make_timeline(r, duration, stats, styles)
    speech = [speech_signals(r, timeline.tracks[p], styles[p], n_frames, FPS, SAMPLE_RATE) for p in range(2)]
    spont = [behaviour.spontaneous(r, styles[p], speech[p], timeline.tracks[p], timeline.tracks[1 - p], FPS)
             for p in range(2)]
    w = world()
    motions = [behaviour.motion(r, styles[p], w, speech[p], timeline.tracks[p], spont[p], spont[1 - p], FPS)
               for p in range(2)]
    participants = tuple(Participant(name=PARTICIPANTS[p], motion=motions[p], audio=speech[p].audio,
                                     identity=styles[p].identity) for p in range(2))
    tracks = {PARTICIPANTS[p]: timeline.tracks[p] for p in range(2)}
    meta = {
        "generator": {"name": "dyadbench.synth", "version": GENERATOR_VERSION, "seed": seed, "split": split,
                      "index": index, "style_pool": pool_name},
        "speaking": {PARTICIPANTS[p]: speech[p].speaking for p in range(2)},
        "envelope": {PARTICIPANTS[p]: speech[p].envelope.astype(np.float32) for p in range(2)},
        "turns": [(PARTICIPANTS[h], s, e) for h, s, e in timeline.turns],
        "segments": {name: [(float(s), float(e), k) for (s, e), k in zip(t.phrases, t.kinds)]
                     for name, t in tracks.items()},
        "events": {name: {"phrase_end": t.phrase_ends("phrase"), "emphasis": t.emphasis_times()}
                   for name, t in tracks.items()},
        "responded_events": {PARTICIPANTS[p]: spont[p].responded_events for p in range(2)},
        "styles": {PARTICIPANTS[p]: styles[p].as_dict() for p in range(2)},
    }
    return DyadicClip(clip_id=clip_name(split, index), participants=participants, fps=FPS,
                      sample_rate=SAMPLE_RATE, layout="flame56", meta=meta)


def make_clips(split: str, n: int, seed: int = 0, duration_s: float | None = None) -> list[DyadicClip]:
    """The first ``n`` clips of ``split`` in memory (see the module docstring for what they contain)."""
    if n < 0:
        raise ConfigError(f"number of clips must be >= 0, got {n}")
    return [make_clip(split, i, seed, duration_s) for i in range(n)]
