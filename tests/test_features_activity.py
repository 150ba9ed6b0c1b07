"""Energy VAD, speech segments and turn counting."""

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from dyadbench.features.activity import count_turns, energy_vad, runs, segments_mask
from dyadbench.synth.corpus import make_clips


def test_vad_on_a_tone_burst():
    sr, fps = 16_000, 25.0
    audio = np.random.default_rng(0).normal(0, 1e-3, sr * 4).astype(np.float32)
    t = np.arange(sr) / sr
    audio[sr:2 * sr] += 0.3 * np.sin(2 * np.pi * 200 * t)  # speech-like burst in second 1-2
    vad = energy_vad(audio, sr, fps)
    assert vad.shape == (100,)
    assert vad[25:50].all() and not vad[:24].any() and not vad[51:].any()


def test_silence_has_no_speech():
    assert not energy_vad(np.zeros(16_000, np.float32)).any()


def test_vad_agrees_with_the_generator():
    for clip in make_clips("test", 4, seed=2):
        for p in clip.participants:
            assert (energy_vad(p.audio) == clip.meta["speaking"][p.name]).mean() > 0.93


def test_segments_mask_uses_frame_centres():
    mask = segments_mask([(0.0, 0.1), (0.5, 0.58)], 20, 25.0)
    assert np.flatnonzero(mask).tolist() == [0, 1, 12, 13]


def test_count_turns_ignores_backchannels():
    fps = 25.0
    a = segments_mask([(0, 3), (6, 9)], 300, fps)
    b = segments_mask([(3.2, 5.5), (7.0, 7.4)], 300, fps)  # one real turn, one back-channel
    assert count_turns([a, b], fps) == 3
    assert count_turns([a, np.zeros(300, bool)], fps) == 1
    assert count_turns([np.zeros(300, bool)] * 2, fps) == 0


@settings(max_examples=50, deadline=None)
@given(st.lists(st.booleans(), max_size=60))
def test_runs_reconstruct_the_mask(values):
    mask = np.array(values, dtype=bool)
    rebuilt = np.zeros(len(mask), dtype=bool)
    for start, stop in runs(mask):
        assert stop > start
        rebuilt[start:stop] = True
    assert np.array_equal(rebuilt, mask)
