"""Input perturbations of the robustness protocol: burst masks, hold-last drop, SNR noise, seeding, and what
they leave untouched (the ground truth, the other participant, the oracle's inputs)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from dyadbench.datasets.base import DyadicClip, InMemorySource, Participant
from dyadbench.errors import ConfigError, InputError
from dyadbench.protocol.config import ProtocolConfig
from dyadbench.protocol.noise_scale import resolve_noise_scale
from dyadbench.protocol.perturbations import (Perturbation, burst_mask, hold_last, parse, perturb_signal,
                                              perturbed_inputs)
from dyadbench.protocol.runner import evaluate
from tests.protocol_clips import isolated_cache, make_clip, make_source  # noqa: F401

N = 2_000_000  # positions of the statistical mask tests


def _runs(mask: np.ndarray) -> np.ndarray:
    """Lengths of the maximal runs of True."""
    edges = np.diff(np.concatenate([[0], mask.astype(np.int8), [0]]))
    return np.flatnonzero(edges == -1) - np.flatnonzero(edges == 1)


@pytest.mark.parametrize("occupancy", [0.1, 0.3, 0.7])
def test_burst_mask_occupancy_and_burst_length_converge(occupancy):
    # tolerance: 0.01 absolute on the occupied fraction (its standard error over ~2e6/(25/q) bursts is < 0.003);
    # runs of True: a burst of mean m = 25 is followed at once by another with probability p (a gap of 0), so a
    # run holds a geometric number of bursts, mean 1/(1 - p), with p = q / (q + m (1 - q)): mean run m / (1 - p),
    # within 3 %
    m = 25.0
    mask = burst_mask(N, occupancy, m, np.random.default_rng(1))
    assert abs(mask.mean() - occupancy) < 0.01
    p = occupancy / (occupancy + m * (1 - occupancy))
    assert _runs(mask).mean() == pytest.approx(m / (1 - p), rel=0.03)


def test_burst_mask_edges():
    rng = np.random.default_rng(0)
    assert burst_mask(100, 1.0, 4, rng).all()
    assert _runs(burst_mask(N // 10, 0.5, 1, rng)).max() > 1  # adjacent one-frame bursts merge
    with pytest.raises(ConfigError):
        Perturbation("partner-motion", "drop", 0.0)
    with pytest.raises(ConfigError):
        parse("partner-motion:silence:0.3")
    with pytest.raises(ConfigError, match="one perturbation per target and kind"):
        ProtocolConfig(perturbations=(parse("partner-motion:drop:0.3"), parse("partner-motion:drop:0.5")))


def test_hold_last_drop_by_hand():
    x = np.array([[0.0, 10], [1, 11], [2, 12], [3, 13], [4, 14], [5, 15]])
    mask = np.array([True, False, True, True, False, True])  # frame 0 is never replaced
    np.testing.assert_array_equal(hold_last(x, mask), [[0, 10], [1, 11], [1, 11], [1, 11], [4, 14], [4, 14]])
    everything = perturb_signal(x, [parse("partner-motion:drop:1")], 25.0, seed=0, clip_id="c", participant="p",
                                noise_scale=None)
    np.testing.assert_array_equal(everything, np.repeat(x[:1], 6, axis=0))


def test_speech_noise_has_the_power_of_its_snr():
    t = np.arange(16_000 * 30) / 16_000
    x = (0.5 * np.sin(2 * np.pi * 220 * t)).astype(np.float32)  # power 0.125
    noisy = perturb_signal(x, [parse("partner-speech:noise:1:1:20")], 16_000, seed=0, clip_id="c",
                           participant="p", noise_scale=None)
    added = noisy.astype(np.float64) - x
    assert added.var() == pytest.approx(0.125 / 10 ** 2, rel=0.02) and abs(added.mean()) < 1e-3
    partial = perturb_signal(x, [parse("partner-speech:noise:0.3:0.1:20")], 16_000, seed=0, clip_id="c",
                             participant="p", noise_scale=None)
    assert abs((partial != x).mean() - 0.3) < 0.1  # 30 s of 0.1-s bursts
    silenced = perturb_signal(x, [parse("partner-speech:noise:1:1:20"), parse("partner-speech:silence:1")],
                              16_000, seed=0, clip_id="c", participant="p", noise_scale=None)
    assert not silenced.any()  # noise first, then silence


def _clip_with_features() -> DyadicClip:
    clip = make_clip("c000", 4.0)
    people = tuple(Participant(p.name, p.motion, p.audio, p.identity,
                               np.zeros((p.motion.shape[0] * 4, 8), np.float32)) for p in clip.participants)
    return DyadicClip(clip.clip_id, people)


def test_what_is_perturbed_and_what_is_not():
    clip = make_clip("c000", 8.0)
    every = tuple(parse(t) for t in ("partner-motion:gaussian:0.5", "partner-speech:silence:0.5",
                                     "agent-speech:noise:0.5:1:10"))
    seen = perturbed_inputs(clip, "speaker1", every, seed=0, noise_scale=0.3)
    agent, partner = seen.participant("speaker1"), seen.participant("speaker2")
    assert agent.motion is clip.participant("speaker1").motion  # ground truth untouched
    assert partner.motion.shape == clip.participant("speaker2").motion.shape
    assert not np.array_equal(partner.motion, clip.participant("speaker2").motion)
    assert not np.array_equal(partner.audio, clip.participant("speaker2").audio)
    assert not np.array_equal(agent.audio, clip.participant("speaker1").audio)
    only_motion = perturbed_inputs(clip, "speaker1", every[:1], seed=0, noise_scale=0.3)
    assert only_motion.participant("speaker2").audio is clip.participant("speaker2").audio
    assert only_motion.participant("speaker1") is clip.participant("speaker1")
    again = perturbed_inputs(clip, "speaker1", every, seed=0, noise_scale=0.3)
    np.testing.assert_array_equal(again.participant("speaker2").motion, partner.motion)  # same seed, same draw
    other = perturbed_inputs(clip, "speaker1", every, seed=1, noise_scale=0.3)
    assert not np.array_equal(other.participant("speaker2").motion, partner.motion)
    with pytest.raises(InputError, match="speech perturbations act on waveforms"):
        perturbed_inputs(_clip_with_features(), "speaker1", every[1:2], seed=0, noise_scale=None)


def test_noise_scale_is_the_mean_per_dimension_std_of_the_train_motion():
    # dim d of every frame alternates +-a_d, so its std is a_d; sigma = round(mean a_d, 3)
    frames, amplitude = 100, np.linspace(0.01, 1.0, 56)
    motion = (np.where(np.arange(frames)[:, None] % 2, 1.0, -1.0) * amplitude).astype(np.float32)
    people = tuple(Participant(name, motion, np.zeros(16_000 * 4, np.float32)) for name in ("speaker1", "speaker2"))
    train = InMemorySource([DyadicClip("t0", people)], split="train")
    config = ProtocolConfig(perturbations=(parse("partner-motion:laplace:0.5"),))
    assert resolve_noise_scale(config, lambda: train).noise_scale == round(float(amplitude.mean()), 3)
    with pytest.raises(ConfigError, match="--noise-scale"):
        resolve_noise_scale(config, None)
    drop = ProtocolConfig(perturbations=(parse("partner-motion:drop:0.5"),))
    assert resolve_noise_scale(drop, None) is drop


def _run(model: str, source, *perturbations: str, noise_scale: float | None = None, predictions=None):
    config = ProtocolConfig(context=1, perturbations=tuple(parse(p) for p in perturbations), noise_scale=noise_scale)
    return evaluate(model, source, config, progress=False, predictions_dir=predictions)


def test_clip_order_does_not_change_a_clip_perturbation(tmp_path):
    both, alone = make_source(2), InMemorySource([make_source(2).load("c001")], dataset="handmade")
    _run("mime", both, "partner-motion:uniform:0.5:0.2", noise_scale=0.2, predictions=tmp_path / "a")
    _run("mime", alone, "partner-motion:uniform:0.5:0.2", noise_scale=0.2, predictions=tmp_path / "b")
    for stem in ("c001_speaker1", "c001_speaker2"):  # second of two clips, or the only one
        np.testing.assert_array_equal(np.load(tmp_path / "a" / f"{stem}.npy"), np.load(tmp_path / "b" / f"{stem}.npy"))


def test_oracle_and_input_free_models_are_unaffected_and_the_run_is_recorded():
    source = make_source(2)
    partner = ("partner-motion:gaussian:0.7", "partner-speech:silence:0.7", "agent-speech:silence:1:4")
    for model in ("oracle", "zero"):  # the oracle reads the agent's ground truth; zero reads nothing
        clean, perturbed = _run(model, source), _run(model, source, *partner, noise_scale=0.5)
        assert perturbed.metrics == clean.metrics  # ground truth and the scored partner motion untouched
    assert perturbed.protocol.perturbations == "+".join(parse(p).text() for p in partner)
    assert perturbed.configuration["perturbations"] == perturbed.protocol.perturbations
    assert perturbed.protocol.noise_scale == 0.5 and "derive_seed(0, 'perturbation'" in perturbed.notes[0]


def test_mime_mse_grows_by_occupancy_times_noise_variance():
    # mime outputs the partner's motion; gaussian noise e (std sigma) on a fraction q of its frames adds
    # E[e^2] = sigma^2 on those frames and a zero-mean cross term: MSE_noisy - MSE_clean ~ q sigma^2 per dim
    # (1-frame bursts over 60-s clips keep the realised occupancy within a few %; tolerance 10 %)
    source, sigma, q = make_source(2, seconds=60.0), 0.5, 0.3
    clean = _run("mime", source)
    noisy = _run("mime", source, "partner-motion:gaussian:0.3:0.04", noise_scale=sigma)
    for component in ("exp", "jaw", "pose"):
        increase = noisy.metrics[f"mse_{component}"] - clean.metrics[f"mse_{component}"]
        assert increase == pytest.approx(q * sigma ** 2, rel=0.1), component
    assert math.isclose(_run("mime", source, "partner-speech:noise:0.5").metrics["mse_exp"],
                        clean.metrics["mse_exp"])
