"""Version 2 of the embedded synthetic corpus: v1's conversations plus dynamics that play out over many seconds.

Everything of v1 (:mod:`dyadbench.synth.corpus`: people, turn-taking, speech, the fast causal table) is
reused unchanged; v2 adds four long-range mechanisms, each observable from what a model receives (the
partner's motion and speech, the agent's own speech), each with a switch (:class:`Dynamics`; off = the
mechanism removed, every other random draw unchanged). Clip ``i`` depends only on (seed, split, i, the
switches). Per person, two persistent v2 traits are drawn from (seed, identity): ``mood_gain`` and
``engage_gain``, both uniform 0.8-1.2.

What drives what (v2 section of the causal table; all causal; u_mood and u_engage are expression modes
of their own, orthogonal to v1's affect modes, see :func:`directions`)::

    mechanism (source)                   state, time constant                  drives (gain)
    shared mood (Barsade 2002, mood      m(t): OU shared by both people,       both faces: + 1.0 mood_gain m
    contagion; vocal arousal cues,       tau 20 s, unit variance               along u_mood; both voices
    Scherer 2003)                                                              (:mod:`~dyadbench.synth.speech_v2`):
                                                                               f0 level x (1 + 0.06 m), pitch
                                                                               range ^(1 + 0.3 m), loudness
                                                                               x (1 + 0.15 m)
    entrainment / emotional contagion    c(t) = 1 - exp(-t / 30 s) from the    own affect (idle, smiles, brow
    (Hatfield, Cacioppo & Rapson 1994;   clip start                            raises) x g_exp(t); head
    Chartrand & Bargh 1999; Levitan &                                          deviation from its mean
    Hirschberg 2011)                                                           x g_head(t); g = 1 + 0.6 c
                                                                               (E_partner / E_own - 1), E =
                                                                               affect_std (exp), idle_head_std
                                                                               + head_speak_amp + nod_amp (head)
    listener engagement (Ward &          e(t): follower of "the partner        listener face: + 1.5
    Tsukahara 2000; Bavelas, Coates &    holds the floor", rise tau 5 s        engage_gain e along u_engage;
    Johnson 2000)                        while it talks, decay tau 2 s after   nod probability x (0.4 + 0.6 e)
    nod excitation (Hadar, Steiner &     h(t): own earlier nods + 0.5 x the    nod probability x clip(1 + 0.25
    Rose 1985; Maynard 1987)             partner's, each exp(-dt / 6 s)        (h - 2), 0.3, 1.6)
                                                                               (:mod:`~dyadbench.synth.nodding`)

Causal graph: m -> (both faces, both voices); c -> (energy gains of both); partner turns -> e_listener
-> (listener face, listener nods); nods (past, both people) -> nods. What a model sees: m in the
partner's face at every frame (its own expression mode, so the current 1-s turn already shows it) and
in both voices; e only through how long the partner has been talking, which one 1-s turn cannot show
and several turns of history can; g through the partner's motion energy, which builds over tens of
seconds; h through the partner's past nods. On a quick causal ridge check (per-turn summaries of the
visible inputs, 100 train / 30 test clips) MSE exp at n = 7 is 12.1 % below n = 0 with every mechanism
on; the gain comes from e: without the engagement it is 0.0 %, without the mood 12.5 %, without the
contagion 12.0 % (v1: 1.6 %).

Measured (task D's estimator, :mod:`dyadbench.headroom`, fitted on 200 v2 train and 40 val clips, 100
test clips): n = 7 vs n = 0 on test, MSE exp -14.9 % [95 % interval -15.8, -14.0], P-FD exp -14.9 %
[-16.3, -13.6], FD exp -12.6 %; pose about 0 (the nod mechanisms add no measurable pose headroom). v1 with
the same estimator: MSE exp -2.0 %, P-FD exp -2.6 %. The realism checks of v1 pass on v2
(tests/test_synth_v2_realism.py); exp per-dim std is 0.60 on 20 test clips (v1 0.45; the two real
DualTalk clips 0.54 and 0.40), 0.71 on ood (v1 0.60).

This table lives here rather than in :mod:`dyadbench.synth.corpus`: that module's bytes are part of v1's
generator digest (:func:`dyadbench.synth.writers.generator_digest`), the identity every committed v1
result records, so v1's modules stay byte-identical.

v2 replaces v1's nods by :mod:`~dyadbench.synth.nodding` (same candidate events, amplitudes and lags) and
keeps every other v1 behaviour. ``clip.meta["conversation"]`` holds the latent states (mood, engagement,
energy gains, nod frames) and the switches, for tests; the written DualTalk files hold none of it.
"""

from __future__ import annotations

from dataclasses import replace
from functools import lru_cache

import numpy as np

from dyadbench.datasets.base import DyadicClip, Participant
from dyadbench.errors import ConfigError
from dyadbench.motion import FPS, SAMPLE_RATE
from dyadbench.seeding import rng as seeded_rng
from dyadbench.synth import behaviour, conversation, nodding
from dyadbench.synth.corpus import PARTICIPANTS, _duration, clip_name
from dyadbench.synth.signals import causal_response, nod_kernel
from dyadbench.synth.speech_v2 import Prosody, speech_signals
from dyadbench.synth.styles import EXP_DIM, SPLIT_STATS, Style, split_pool, style_pool, world
from dyadbench.synth.timeline import make_timeline

VERSION = 2
MOOD_EXP, ENGAGE_EXP = 1.0, 2.0  # expression gain per unit mood / engagement
HEAD = slice(EXP_DIM + 3, EXP_DIM + 6)


@lru_cache(maxsize=1)
def directions() -> tuple[np.ndarray, np.ndarray]:
    """(u_mood, u_engage): (50,) expression directions of the mood and of listener engagement.

    Drawn like the world's affect modes (dims weighted by 0.3 + exp(-d / 20) x the world's per-dim scale),
    made orthogonal to those modes and to each other (Gram-Schmidt) and scaled to their norm: the slow
    states move expression modes of their own, leaving v1's fast modes (smile, brow, mirrored affect) as
    they were.
    """
    w = world()
    d = np.arange(EXP_DIM)
    raw = seeded_rng("dyadbench-synth-v2-directions", VERSION).standard_normal((2, EXP_DIM))
    raw *= (0.3 + np.exp(-d / 20.0)) * w.dim_scale
    basis = [row / np.linalg.norm(row) for row in np.linalg.qr(w.affect.T)[0].T]
    out = []
    for row in raw:
        for b in basis:
            row = row - (row @ b) * b
        basis.append(row / np.linalg.norm(row))
        out.append(basis[-1] * np.linalg.norm(w.affect[0]))
    return out[0], out[1]


def traits(seed: int, identity: str) -> tuple[float, float]:
    """A person's persistent (mood_gain, engage_gain), deterministic in (seed, identity)."""
    r = seeded_rng(seed, "v2-traits", identity, VERSION)
    return float(r.uniform(0.8, 1.2)), float(r.uniform(0.8, 1.2))


def head_energy(style: Style) -> float:
    return style.idle_head_std + style.head_speak_amp + style.nod_amp


def make_clip(split: str, index: int, seed: int = 0, duration_s: float | None = None,
              dynamics: conversation.Dynamics = conversation.Dynamics()) -> DyadicClip:
    """Clip ``index`` of ``split`` (deterministic in seed, split, index, the switches and the version)."""
    pool_name = split_pool(split)
    stats = SPLIT_STATS[pool_name]
    pool = style_pool(pool_name, seed)
    r = seeded_rng(seed, split, index, "clip", VERSION)
    a, b = r.choice(len(pool), size=2, replace=False)
    styles = (pool[a], pool[b])
    duration = _duration(r, stats.duration_mean_s) if duration_s is None else float(duration_s)
    n = int(round(duration * FPS))
    if n < 1:
        raise ConfigError(f"clip duration must be at least one frame, got {duration_s} s")
    timeline = make_timeline(r, n / FPS, stats, styles)
    tracks = timeline.tracks
    mood = conversation.shared_mood(seeded_rng(seed, split, index, "mood", VERSION), n, FPS, dynamics.mood)
    progress = conversation.convergence(n, FPS, dynamics.contagion)
    engage = [conversation.engagement(conversation.floor_mask(timeline.turns, 1 - p, n, FPS), FPS,
                                      dynamics.engagement) for p in range(2)]
    speech = [speech_signals(r, tracks[p], styles[p], n, FPS, SAMPLE_RATE, Prosody.from_mood(mood)) for p in range(2)]
    silent = [replace(s, nod_prob=0.0) for s in styles]  # v1's own nods are replaced by v2's below
    spont = [behaviour.spontaneous(r, silent[p], speech[p], tracks[p], tracks[1 - p], FPS) for p in range(2)]
    candidates = []
    for p in range(2):
        events = behaviour.partner_events(tracks[1 - p], FPS)
        events = events[events < n]
        candidates.append(events[~speech[p].speaking[events]])
    nods = nodding.nod_frames(seeded_rng(seed, split, index, "nods", VERSION), tuple(candidates),
                              (styles[0].nod_prob, styles[1].nod_prob),
                              tuple(nodding.engage_factor(e, dynamics.engagement) for e in engage), FPS,
                              dynamics.nod_excitation)
    gain_exp = [conversation.energy_gain(styles[p].affect_std, styles[1 - p].affect_std, progress) for p in range(2)]
    gain_head = [conversation.energy_gain(head_energy(styles[p]), head_energy(styles[1 - p]), progress)
                 for p in range(2)]
    nod_rng = seeded_rng(seed, split, index, "nod-amp", VERSION)
    spont = [replace(spont[p], affect=spont[p].affect * gain_exp[p][:, None],
                     listener_nod=styles[p].nod_amp * causal_response(
                         n, nods[p] + int(round(styles[p].nod_lag_s * FPS)), nod_kernel(FPS),
                         nod_rng.uniform(0.7, 1.3, len(nods[p]))),
                     responded_events=np.union1d(spont[p].responded_events, nods[p])) for p in range(2)]
    w = world()
    u_mood, u_engage = directions()
    motions = []
    for p in range(2):
        m = behaviour.motion(r, styles[p], w, speech[p], tracks[p], spont[p], spont[1 - p], FPS).astype(np.float64)
        mood_gain, engage_gain = traits(seed, styles[p].identity)
        m[:, :EXP_DIM] += (np.outer(MOOD_EXP * mood_gain * mood, u_mood)
                           + np.outer(ENGAGE_EXP * engage_gain * engage[p], u_engage))
        mean = np.asarray(styles[p].head_mean)
        m[:, HEAD] = mean + (m[:, HEAD] - mean) * gain_head[p][:, None]
        motions.append(m.astype(np.float32))
    participants = tuple(Participant(name=PARTICIPANTS[p], motion=motions[p], audio=speech[p].audio,
                                     identity=styles[p].identity) for p in range(2))
    named = {PARTICIPANTS[p]: tracks[p] for p in range(2)}
    meta = {
        "generator": {"name": "dyadbench.synth", "version": VERSION, "seed": seed, "split": split,
                      "index": index, "style_pool": pool_name, "dynamics": dynamics.as_dict()},
        "speaking": {PARTICIPANTS[p]: speech[p].speaking for p in range(2)},
        "envelope": {PARTICIPANTS[p]: speech[p].envelope.astype(np.float32) for p in range(2)},
        "turns": [(PARTICIPANTS[h], s, e) for h, s, e in timeline.turns],
        "segments": {name: [(float(s), float(e), k) for (s, e), k in zip(t.phrases, t.kinds)]
                     for name, t in named.items()},
        "events": {name: {"phrase_end": t.phrase_ends("phrase"), "emphasis": t.emphasis_times()}
                   for name, t in named.items()},
        "responded_events": {PARTICIPANTS[p]: spont[p].responded_events for p in range(2)},
        "styles": {PARTICIPANTS[p]: styles[p].as_dict() for p in range(2)},
        "conversation": {"mood": mood, "progress": progress,
                         "engagement": {PARTICIPANTS[p]: engage[p] for p in range(2)},
                         "gain_exp": {PARTICIPANTS[p]: gain_exp[p] for p in range(2)},
                         "gain_head": {PARTICIPANTS[p]: gain_head[p] for p in range(2)},
                         "nod_candidates": {PARTICIPANTS[p]: candidates[p] for p in range(2)},
                         "nods": {PARTICIPANTS[p]: nods[p] for p in range(2)}},
    }
    return DyadicClip(clip_id=clip_name(split, index), participants=participants, fps=FPS,
                      sample_rate=SAMPLE_RATE, layout="flame56", meta=meta)


def make_clips(split: str, n: int, seed: int = 0, duration_s: float | None = None,
               dynamics: conversation.Dynamics = conversation.Dynamics()) -> list[DyadicClip]:
    """The first ``n`` v2 clips of ``split`` in memory (see the module docstring)."""
    if n < 0:
        raise ConfigError(f"number of clips must be >= 0, got {n}")
    return [make_clip(split, i, seed, duration_s, dynamics) for i in range(n)]
