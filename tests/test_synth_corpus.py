"""The synthetic corpus: data model, determinism, persistent styles, calibration, ood differences."""

import numpy as np
import pytest

from dyadbench.datasets.statistics import motion_statistics
from dyadbench.errors import ConfigError
from dyadbench.features.activity import count_turns
from dyadbench.synth.calibration import REAL_CLIPS, calibration_range
from dyadbench.synth.corpus import make_clip, make_clips
from dyadbench.synth.styles import STYLE_RANGES, style_pool


@pytest.fixture(scope="module")
def train_clips():
    return make_clips("train", 8, seed=0)


@pytest.fixture(scope="module")
def ood_clips():
    return make_clips("ood", 8, seed=0)


def test_clip_layout_and_dtypes():
    clip = make_clip("test", 0, seed=0, duration_s=6.0)
    assert clip.layout == "flame56" and clip.fps == 25.0 and clip.sample_rate == 16_000
    assert [p.name for p in clip.participants] == ["speaker1", "speaker2"]
    for p in clip.participants:
        assert p.motion.shape == (150, 56) and p.motion.dtype == np.float32
        assert p.audio.shape == (150 * 640,) and p.audio.dtype == np.float32
        assert np.all(np.isfinite(p.motion)) and np.abs(p.audio).max() < 1.0
        assert p.identity.startswith("synth-seen-")
        speaking = clip.meta["speaking"][p.name]
        assert speaking.shape == (150,) and speaking.dtype == bool
    assert clip.participants[0].identity != clip.participants[1].identity


def test_deterministic_and_subset_stable():
    a = make_clips("test", 3, seed=4, duration_s=5.0)
    b = make_clip("test", 2, seed=4, duration_s=5.0)
    for p, q in zip(a[2].participants, b.participants):
        assert np.array_equal(p.motion, q.motion) and np.array_equal(p.audio, q.audio)
    other_seed = make_clip("test", 2, seed=5, duration_s=5.0)
    assert not np.array_equal(other_seed.participants[0].motion, b.participants[0].motion)


def test_unknown_split_is_refused():
    with pytest.raises(ConfigError, match="unknown synthetic split"):
        make_clip("dev", 0)


def test_audio_is_speech_while_speaking_and_near_silence_otherwise(train_clips):
    for clip in train_clips[:3]:
        for p in clip.participants:
            frames = p.audio[: clip.num_frames * 640].reshape(clip.num_frames, 640)
            rms = np.sqrt((frames.astype(np.float64) ** 2).mean(axis=1))
            speaking = clip.meta["speaking"][p.name]
            assert np.median(rms[~speaking]) < 2e-3
            assert np.median(rms[speaking]) > 20 * np.median(rms[~speaking])


def test_styles_persist_across_clips():
    seen: dict[str, dict] = {}
    for clip in make_clips("train", 30, seed=0, duration_s=2.0):
        for p in clip.participants:
            style = clip.meta["styles"][p.name]
            assert seen.setdefault(p.identity, style) == style
    assert len(seen) < 60  # the pool is finite: people recur


def test_ood_people_are_unseen():
    seen = {s.identity for s in style_pool("seen", 0)}
    ood = {p.identity for c in make_clips("ood", 6, seed=0, duration_s=2.0) for p in c.participants}
    assert ood and not ood & seen


def test_statistics_within_calibration_ranges(train_clips, ood_clips):
    for clips in (train_clips, ood_clips):
        stats = [motion_statistics(p.motion, p.audio) for c in clips for p in c.participants]
        for name in REAL_CLIPS:
            lo, hi = calibration_range(name)
            value = float(np.mean([s[name] for s in stats]))
            assert lo <= value <= hi, (name, value, lo, hi)


def test_talk_and_overlap_fractions_within_calibration(train_clips):
    talk, overlap = [], []
    for clip in train_clips:
        a, b = (clip.meta["speaking"][n] for n in ("speaker1", "speaker2"))
        talk += [a.mean(), b.mean()]
        overlap.append((a & b).sum() / max(1, (a | b).sum()))
    assert 0.24 / 3 <= np.mean(talk) <= 0.41 * 3
    assert 0.19 / 3 <= np.mean(overlap) <= 0.20 * 3


def test_mean_clip_length_is_dualtalk_like():
    lengths = [make_clip("test", i, seed=0).duration_s for i in range(40)]
    assert 26.0 <= np.mean(lengths) <= 36.0


def test_ood_differs_measurably_from_train(train_clips, ood_clips):
    def summary(clips):
        turns = [count_turns([c.meta["speaking"][n] for n in ("speaker1", "speaker2")], c.fps) / c.duration_s
                 for c in clips]
        styles = [c.meta["styles"][n] for c in clips for n in ("speaker1", "speaker2")]
        return (np.mean(turns), np.mean([s["syllable_rate"] for s in styles]),
                np.mean([s["nod_lag_s"] for s in styles]),
                np.mean([motion_statistics(p.motion)["head_std"] for c in clips for p in c.participants]))

    train_turn_rate, train_rate, train_lag, train_head = summary(train_clips)
    ood_turn_rate, ood_rate, ood_lag, ood_head = summary(ood_clips)
    assert ood_turn_rate > 1.5 * train_turn_rate  # shorter turns
    assert ood_rate > STYLE_RANGES["seen"]["syllable_rate"][1] >= train_rate  # faster talkers
    assert ood_lag > train_lag + 0.1  # later nods
    assert ood_head > 1.2 * train_head  # livelier heads
