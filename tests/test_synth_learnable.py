"""The corpus is learnable: a causal linear model on conversation features beats the input-blind
baselines, and the baselines order as documented in dyadbench.synth.corpus."""

import numpy as np
import pytest
from sklearn.linear_model import Ridge

from dyadbench.features.activity import energy_vad, runs
from dyadbench.features.logmel import logmel_frames, rms_envelope
from dyadbench.motion import EXP, JAW
from dyadbench.synth.corpus import make_clips

SPEAKERS = ("speaker1", "speaker2")


def past(x: np.ndarray, lags) -> np.ndarray:
    """Columns x[t - lag] (zeros before the start): only the present and the past."""
    cols = []
    for lag in lags:
        shifted = np.zeros_like(x)
        shifted[lag:] = x[: len(x) - lag]
        cols.append(shifted)
    return np.concatenate(cols, axis=1)


def features(clip, agent):
    own, partner = clip.participant(agent), clip.partner_of(agent)
    n = clip.num_frames
    own_level = np.log(rms_envelope(own.audio)[:n, None] + 1e-4)
    partner_level = np.log(rms_envelope(partner.audio)[:n, None] + 1e-4)
    offsets = np.zeros((n, 1))
    ends = runs(energy_vad(partner.audio)[:n])[:, 1]
    offsets[ends[ends < n], 0] = 1.0
    partner_exp = partner.motion[:n, EXP].astype(float)
    return np.concatenate([past(own_level, range(5)), past(logmel_frames(own.audio, n_mels=16)[:n], range(4)),
                           past(partner_level, range(0, 25, 2)), past(offsets, range(30)),
                           past(partner_exp - partner_exp.mean(axis=0), (0, 6, 12, 18))], axis=1)


@pytest.fixture(scope="module")
def results():
    train, test = make_clips("train", 16, seed=0, duration_s=15.0), make_clips("test", 6, seed=0, duration_s=15.0)
    x = np.concatenate([features(c, a) for c in train for a in SPEAKERS])
    y = np.concatenate([c.participant(a).motion.astype(float) for c in train for a in SPEAKERS])
    model, mean = Ridge(alpha=10.0).fit(x, y), y.mean(axis=0)
    mse: dict[str, list] = {k: [] for k in ("mean-frame", "mime", "lagged-mirror", "ridge")}
    for clip in test:
        for agent in SPEAKERS:
            gt = clip.participant(agent).motion.astype(float)
            partner = clip.partner_of(agent).motion.astype(float)
            preds = {"mean-frame": np.broadcast_to(mean, gt.shape), "mime": partner,
                     "lagged-mirror": np.concatenate([np.repeat(partner[:1], 12, axis=0), partner[:-12]]),
                     "ridge": model.predict(features(clip, agent))}
            for name, pred in preds.items():
                mse[name].append([((pred[:, s] - gt[:, s]) ** 2).mean() for s in (EXP, JAW)])
    return {k: np.mean(v, axis=0) for k, v in mse.items()}  # [exp, jaw]


def test_conversation_model_beats_baselines(results):
    for baseline in ("mean-frame", "mime", "lagged-mirror"):
        assert results["ridge"][0] < 0.85 * results[baseline][0], baseline  # expression
        assert results["ridge"][1] < 0.7 * results[baseline][1], baseline  # jaw


def test_baselines_order_as_documented(results):
    assert results["mime"][0] > results["mean-frame"][0]  # copying the partner costs MSE
    assert results["lagged-mirror"][0] < results["mime"][0]  # mirroring happens with a lag
