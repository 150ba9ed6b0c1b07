"""The causal structure of the synthetic corpus, measured the way a model would see it."""

import numpy as np
import pytest

from dyadbench.features.activity import energy_vad, runs
from dyadbench.features.logmel import rms_envelope
from dyadbench.datasets.statistics import best_lagged_r
from dyadbench.synth.corpus import make_clips
from dyadbench.synth.styles import world

LAGS = np.arange(-25, 26)


@pytest.fixture(scope="module")
def clips():
    return make_clips("train", 10, seed=5)


def lagged_r(x, y, lag):
    """Pearson r of x[t] with y[t + lag]."""
    if lag >= 0:
        a, b = x[: len(x) - lag], y[lag:]
    else:
        a, b = x[-lag:], y[: len(y) + lag]
    return np.corrcoef(a, b)[0, 1]


def triggered_average(events, y):
    """Mean of the z-scored y around each event, for lags LAGS."""
    z = (y - y.mean()) / y.std()
    rows = [z[e + LAGS] for e in events if e + LAGS[0] >= 0 and e + LAGS[-1] < len(z)]
    return np.array(rows)


def test_jaw_follows_own_speech_envelope_with_a_small_lag(clips):
    curves = [[lagged_r(rms_envelope(p.audio), p.motion[:, 50].astype(float), lag) for lag in LAGS]
              for c in clips for p in c.participants]
    mean = np.mean(curves, axis=0)
    peak = LAGS[np.argmax(mean)]
    assert 1 <= peak <= 3
    assert mean.max() > 0.5
    assert mean.max() > mean[LAGS == 0][0] + 0.2


def test_jaw_does_not_follow_partner_speech(clips):
    r = [best_lagged_r(rms_envelope(c.partner_of(p.name).audio), p.motion[:, 50].astype(float), 5)
         for c in clips for p in c.participants]
    own = [best_lagged_r(rms_envelope(p.audio), p.motion[:, 50].astype(float), 5)
           for c in clips for p in c.participants]
    assert np.mean(r) < 0.15 < 0.5 < np.mean(own)


def _listener_response(clips, signal):
    rows = []
    for c in clips:
        for p in c.participants:
            partner_speech = energy_vad(c.partner_of(p.name).audio)
            offsets = runs(partner_speech)[:, 1]
            rows.append(triggered_average(offsets[offsets < len(partner_speech)], signal(p.motion)))
    return np.concatenate(rows).mean(axis=0)


def test_listener_nods_after_partner_speech_offsets(clips):
    def head_pitch_speed(m):
        return np.abs(np.diff(m[:, 53].astype(float), prepend=m[0, 53]))

    response = _listener_response(clips, head_pitch_speed)
    peak = LAGS[np.argmax(response)]
    assert 4 <= peak <= 18  # a few hundred ms after the partner stops
    assert response.max() > 0.5  # well above the listener's usual head speed
    assert response[LAGS < 0].max() < 0.5 * response.max()


def test_listener_smiles_after_partner_speech_offsets(clips):
    smile = world().affect[0]

    def smile_mode(m):
        return (m[:, :50].astype(float) - m[:, :50].mean(axis=0)) @ smile / (smile @ smile)

    response = _listener_response(clips, smile_mode)
    peak = LAGS[np.argmax(response)]
    assert 8 <= peak <= 25
    assert response.max() > 0.4
    assert response.max() > response[LAGS == 0][0] + 0.3


def test_expressions_mirror_the_partner_with_a_lag(clips):
    affect = world().affect
    proj = np.linalg.pinv(affect)  # (50, 4): expression -> affect latent

    def latent(m):
        x = m[:, :50].astype(float)
        return (x - x.mean(axis=0)) @ proj

    # both directions of every clip: agent lags partner (lag > 0) and partner lags agent (lag < 0)
    curves = []
    for c in clips:
        for p in c.participants:
            a, b = latent(c.partner_of(p.name).motion), latent(p.motion)
            curves.append([np.mean([lagged_r(a[:, k], b[:, k], lag) for k in (2, 3)]) for lag in LAGS])
    mean = np.mean(curves, axis=0)
    positive = LAGS > 0
    peak = LAGS[positive][np.argmax(mean[positive])]
    assert 8 <= peak <= 16
    assert mean[positive].max() > mean[LAGS == 0][0] + 0.03
