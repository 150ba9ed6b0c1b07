"""Each long-range mechanism of the v2 corpus is measurable in generated clips, and its effect disappears
when its switch is off (same seed: every other random draw is unchanged; the other mechanisms are off
in both runs)."""

from dataclasses import replace

import numpy as np
import pytest

from dyadbench.features.logmel import rms_envelope
from dyadbench.motion import EXP, POSE
from dyadbench.synth.conversation import Dynamics
from dyadbench.synth.corpus_v2 import directions, make_clips

SPEAKERS = ("speaker1", "speaker2")
FPS = 25


def switched(mechanism, clips, seed, duration_s):
    """(on, off): the same clips with only ``mechanism`` of the v2 dynamics on, and with none on."""
    off = Dynamics(mood=False, contagion=False, engagement=False, nod_excitation=False)
    on = replace(off, **{mechanism: True})
    return tuple(make_clips("test", clips, seed=seed, duration_s=duration_s, dynamics=d) for d in (on, off))


def mode(clip, name, direction):
    """The expression of ``name`` projected on ``direction`` (least-squares coefficient per frame)."""
    x = clip.participant(name).motion[:, EXP].astype(float)
    return (x - x.mean(axis=0)) @ direction / (direction @ direction)


def autocorr(x, lag):
    return np.corrcoef(x[:-lag], x[lag:])[0, 1]


@pytest.fixture(scope="module")
def mood_pair():
    return switched("mood", 4, seed=3, duration_s=60.0)


def test_shared_mood_moves_both_faces_slowly(mood_pair):
    u_mood = directions()[0]
    for clips, on in zip(mood_pair, (True, False)):
        # the latent mood of the run with the mood on (same seed: the same draw)
        r = [np.corrcoef(mode(c, n, u_mood), m.meta["conversation"]["mood"])[0, 1]
             for c, m in zip(clips, mood_pair[0]) for n in SPEAKERS]
        lag5 = [autocorr(mode(c, n, u_mood), 5 * FPS) for c in clips for n in SPEAKERS]
        if on:  # OU with tau 20 s: exp(-0.25) = 0.78 at 5 s (less in 60-s clips: the mean is estimated)
            assert np.mean(r) > 0.8 and np.mean(lag5) > 0.4
        else:  # only v1's fast expression noise is left in that mode
            assert abs(np.mean(r)) < 0.15 and abs(np.mean(lag5)) < 0.1


def test_shared_mood_is_heard_in_both_voices(mood_pair):
    def loudness_r(clip, mood):
        """r of the mean log RMS of voiced frames with the mean mood, over 1-s blocks with >= 10 of them."""
        rows = []
        for n in SPEAKERS:
            level = np.log(rms_envelope(clip.participant(n).audio)[: clip.num_frames] + 1e-6)
            voiced = clip.meta["speaking"][n] & (level > np.log(0.02))
            blocks = [(level[b][voiced[b]].mean(), mood[b].mean()) for b in
                      (slice(k, k + FPS) for k in range(0, clip.num_frames - FPS + 1, FPS)) if voiced[b].sum() >= 10]
            rows.append(np.corrcoef(np.array(blocks).T)[0, 1])
        return rows

    mood = [c.meta["conversation"]["mood"] for c in mood_pair[0]]
    on = np.mean([loudness_r(c, m) for c, m in zip(mood_pair[0], mood)])
    off = np.mean([loudness_r(c, m) for c, m in zip(mood_pair[1], mood)])
    assert on > 0.2 and abs(off) < 0.1


@pytest.fixture(scope="module")
def contagion_pair():
    return switched("contagion", 16, seed=1, duration_s=120.0)


def listening_head_energy(clip, name, window):
    """Sum over axes of the std of head rotation in ``window``, on the frames ``name`` is silent."""
    head = clip.participant(name).motion[window, POSE].astype(float)
    return head[~clip.meta["speaking"][name][window]].std(axis=0).sum()


def style_head_energy(clip, name):
    s = clip.meta["styles"][name]
    return s["idle_head_std"] + s["head_speak_amp"] + s["nod_amp"]


def convergence_slope(clips):
    """Slope of log(energy late / energy early) of each person on log(partner's / own style energy)."""
    early, late = slice(0, 20 * FPS), slice(80 * FPS, 120 * FPS)
    x, y = [], []
    for clip in clips:
        for p, q in (SPEAKERS, SPEAKERS[::-1]):
            x.append(np.log(style_head_energy(clip, q) / style_head_energy(clip, p)))
            y.append(np.log(listening_head_energy(clip, p, late) / listening_head_energy(clip, p, early)))
    return np.polyfit(x, y, 1)[0]


def test_head_energy_converges_toward_the_partner_over_the_dialogue(contagion_pair):
    # with contagion, a person whose partner moves more gains energy late in the dialogue (and the other
    # way round): g = 1 + 0.6 c(t) (ratio - 1) gives a slope near 0.6 (0.95 - 0.25) ~ 0.4 here
    on, off = (convergence_slope(clips) for clips in contagion_pair)
    assert on > 0.3
    assert abs(off) < 0.2


@pytest.fixture(scope="module")
def engagement_pair():
    return switched("engagement", 8, seed=2, duration_s=60.0)


def engagement_rise(clips):
    """Listener's u_engage mode 6-8 s into a partner's turn minus 0-1 s into it (turns of >= 8 s)."""
    u = directions()[1]
    rows = []
    for clip in clips:
        for who, start, end in clip.meta["turns"]:
            if end - start < 8.0:
                continue
            listener = SPEAKERS[1 - SPEAKERS.index(who)]
            x = mode(clip, listener, u)
            f = int(start * FPS)
            rows.append(x[f + 6 * FPS: f + 8 * FPS].mean() - x[f: f + FPS].mean())
    return np.mean(rows), len(rows)


def test_listener_engagement_grows_with_how_long_the_partner_has_talked(engagement_pair):
    (on, n_on), (off, n_off) = (engagement_rise(c) for c in engagement_pair)
    assert n_on == n_off >= 10
    assert on > 0.5 and abs(off) < 0.15


@pytest.fixture(scope="module")
def nod_pair():
    return switched("nod_excitation", 12, seed=4, duration_s=40.0)


def nod_rate_after(clips, rich):
    """Share of candidate events a listener nods at, after >= 3 own nods (``rich``) or <= 1 own nod in the
    previous 6 s."""
    hits = []
    for clip in clips:
        conv = clip.meta["conversation"]
        for n in SPEAKERS:
            nods = conv["nods"][n]
            for f in conv["nod_candidates"][n]:
                recent = np.sum((nods < f) & (nods >= f - 6 * FPS))
                if (recent >= 3) if rich else (recent <= 1):
                    hits.append(f in nods)
    return np.mean(hits), len(hits)


def test_nods_excite_later_nods(nod_pair):
    for clips, on in zip(nod_pair, (True, False)):
        (rich, n_rich), (poor, n_poor) = nod_rate_after(clips, True), nod_rate_after(clips, False)
        assert min(n_rich, n_poor) >= 50
        if on:
            assert rich > poor + 0.25
        else:
            assert abs(rich - poor) < 0.08
