"""StyGazeTalk training material: segments, window bank, style pairs, retrieval check, MPGW-sim seed."""

from __future__ import annotations

import numpy as np
import pytest

from dyadbench.datasets.base import DyadicClip, Participant
from dyadbench.errors import InputError
from models.stygazetalk.audio import HOP
from models.stygazetalk.data import Segment, build_window_bank, sample_style_pairs, segments_of
from models.stygazetalk.generation import mpgw_seed
from models.stygazetalk.train_style import retrieval_accuracy, tiled_windows


def _clip(motion: np.ndarray, clip_id: str = "s0", speaker: str = "spk1") -> DyadicClip:
    audio = np.arange(len(motion) * HOP, dtype=np.float32)
    return DyadicClip(clip_id, (Participant("subject", motion.astype(np.float32), audio, identity=speaker),),
                      layout="gaze7")


def test_segments_drop_extreme_frames_and_never_join_across_gaps():
    motion = np.zeros((100, 7))
    motion[30, 4] = 41.0  # dropped (D3)
    motion[60:62, 0] = -45.0
    segs = segments_of(_clip(motion), angle_limit_deg=40.0, min_frames=20)
    assert [(s.start, s.frames) for s in segs] == [(0, 30), (31, 29), (62, 38)]
    assert segments_of(_clip(motion), angle_limit_deg=40.0, min_frames=30)[1].start == 62
    # audio follows the motion frames exactly
    assert segs[2].audio[0] == 62 * HOP and len(segs[2].audio) == 38 * HOP


def test_segments_reject_two_participant_or_flame_clips():
    clip = DyadicClip("d", (Participant("a", np.zeros((10, 56), np.float32), np.zeros(6400, np.float32)),))
    with pytest.raises(InputError, match="gaze7"):
        segments_of(clip, 40.0, 5)


def test_window_bank_holds_one_frame_lag_windows_on_the_grid():
    motion = np.arange(200, dtype=np.float32)[:, None].repeat(7, axis=1)
    seg = Segment("s", "spk", 0, motion, np.zeros(200 * HOP, np.float32))
    bank = build_window_bank([seg], window=50, stride=25, pre=0, motion_norm=lambda x: x,
                             audio_features=lambda w: np.full((len(w) // HOP, 3), w.shape[0], np.float32))
    # u in {25, 50, ..., 150}: u >= 1 and u + M <= 200
    assert bank.motion.shape == (6, 51, 7) and bank.audio.shape == (6, 50, 3)
    assert bank.motion[0, 0, 0] == 24 and bank.motion[0, -1, 0] == 74  # x_{u-1} .. x_{u+M-1}
    assert (bank.audio == 50 * HOP).all()  # window-local audio of exactly M frames
    with_pre = build_window_bank([seg], window=50, stride=25, pre=50, motion_norm=lambda x: x,
                                 audio_features=lambda w: np.zeros((len(w) // HOP, 3), np.float32))
    assert with_pre.motion.shape == (4, 101, 7) and with_pre.motion[0, 0, 0] == 24  # u = 75


def test_style_pairs_are_adjacent_and_same_session_anchors_far_apart():
    rng = np.random.default_rng(0)
    segs = [Segment(f"s{i}", f"spk{i % 2}", 0, np.zeros((1200, 7), np.float32), np.zeros(0, np.float32))
            for i in range(6)]
    a, b = sample_style_pairs(segs, rng, batch=12, window=50, gap_max=5, min_anchor_gap=250)
    assert len(a) == len(b) == 12
    for (ia, sa), (ib, sb) in zip(a, b):
        assert ia == ib and 50 <= sb - sa <= 55 and sb + 50 <= 1200
    for i in range(6):
        starts = sorted(s for j, s in a if j == i)
        assert all(y - x >= 250 for x, y in zip(starts, starts[1:]))
    with pytest.raises(InputError, match="anchors"):
        sample_style_pairs(segs[:1], rng, batch=12, window=50, gap_max=5, min_anchor_gap=250)


def test_retrieval_accuracy_by_hand():
    emb = np.array([[1.0, 0.0], [0.9, 0.1], [0.0, 1.0], [0.1, 0.9], [0.8, 0.2]])
    labels = ["a", "a", "b", "b", "b"]
    acc, chance = retrieval_accuracy(emb, labels)
    # cosine neighbours: 0->1 (hit), 1->0 (hit), 2->3 (hit), 3->2 (hit), 4->1 (a: miss)
    assert acc == pytest.approx(4 / 5)
    assert chance == pytest.approx((1 / 4 + 1 / 4 + 2 / 4 + 2 / 4 + 2 / 4) / 5)
    acc_g, chance_g = retrieval_accuracy(emb[:2], labels[:2], emb[2:], labels[2:])
    assert acc_g == 0.0 and chance_g == 0.0


def test_tiled_windows_do_not_overlap():
    seg = Segment("s", "spk", 0, np.arange(130 * 7, dtype=np.float32).reshape(130, 7), np.zeros(0, np.float32))
    w, speakers, sessions = tiled_windows([seg], 50)
    assert w.shape == (2, 50, 7) and speakers == ["spk", "spk"] and sessions == ["s", "s"]
    assert w[1, 0, 0] == seg.motion[50, 0]


def test_mpgw_seed_corrupts_only_the_eyes_deterministically_and_streams_per_turn():
    rng = np.random.default_rng(1)
    seed = rng.normal(0, 5, (50, 7)).astype(np.float32)
    out = mpgw_seed(seed, 4.0, 2.0, 0, "clip")
    assert np.array_equal(out[:, :3], seed[:, :3])
    assert np.array_equal(out[:, 3:5], out[:, 5:7])  # one cyclopean direction for both eyes
    assert not np.allclose(out[:, 3:5], seed[:, 3:5])
    assert np.array_equal(out, mpgw_seed(seed, 4.0, 2.0, 0, "clip"))
    per_turn = np.concatenate([mpgw_seed(seed[lo:lo + 25], 4.0, 2.0, 0, "clip", offset=lo, total=50)
                               for lo in (0, 25)])
    assert np.array_equal(per_turn, out)


def test_wav2vec_features_need_local_weights_and_say_so():
    from dataclasses import replace

    from dyadbench.errors import ConfigError
    from models.stygazetalk.audio import feature_dim
    from models.stygazetalk.config import get_generator_config

    cfg = replace(get_generator_config("tiny-se64"), audio_features="wav2vec")
    with pytest.raises(ConfigError, match="wav2vec"):
        feature_dim(cfg)
    with pytest.raises(ConfigError, match="wav2vec"):
        feature_dim(replace(cfg, wav2vec_path="/nonexistent/wav2vec2-base-960h"))


def test_cross_session_retrieval_never_matches_a_window_of_its_own_session():
    # windows 0, 1 are session A (speaker x), 2 is session B (speaker x), 3 is session C (speaker y).
    # Query 0's nearest window overall is 1 (same session); across sessions it is 3 (speaker y: a miss).
    emb = np.array([[1.0, 0.0], [0.99, 0.01], [0.0, 1.0], [0.9, 0.1]])
    speakers, sessions = ["x", "x", "x", "y"], ["A", "A", "B", "C"]
    acc, chance = retrieval_accuracy(emb, speakers)
    assert acc == pytest.approx(2 / 4)  # 0->1, 1->0 hit (session A's twin); 2->3, 3->0 miss
    acc_x, chance_x = retrieval_accuracy(emb, speakers, q_sessions=sessions, g_sessions=sessions)
    # candidates: 0,1 -> {2, 3}: nearest 3 (miss); 2 -> {0, 1, 3}: nearest 3 (miss); 3 -> {0, 1, 2}: 0 (miss)
    assert acc_x == 0.0
    assert chance_x == pytest.approx((1 / 2 + 1 / 2 + 2 / 3 + 0 / 3) / 4)
    # a gallery from other sessions of the same speakers
    acc_g, _ = retrieval_accuracy(emb[:1], ["x"], emb[1:], speakers[1:], q_sessions=["A"], g_sessions=sessions[1:])
    assert acc_g == 0.0  # window 1 (session A) excluded, window 3 (speaker y) nearest
    with pytest.raises(ValueError, match="own session"):
        retrieval_accuracy(emb[:2], speakers[:2], q_sessions=sessions[:2], g_sessions=sessions[:2])
    with pytest.raises(ValueError, match="both"):
        retrieval_accuracy(emb, speakers, q_sessions=sessions)


def test_same_speaker_positives_come_from_the_speaker_and_never_overlap_the_anchor():
    rng = np.random.default_rng(1)
    segs = [Segment(f"s{i}", f"spk{i % 3}", 0, np.zeros((400, 7), np.float32), np.zeros(0, np.float32))
            for i in range(6)]
    a, b = sample_style_pairs(segs, rng, batch=12, window=50, gap_max=5, min_anchor_gap=100,
                              positives="same-speaker")
    other_session = 0
    for (ia, sa), (ib, sb) in zip(a, b):
        assert segs[ia].speaker == segs[ib].speaker and 0 <= sb <= 350
        if ia == ib:
            assert abs(sb - sa) >= 50
        other_session += ia != ib
    assert other_session > 0  # the speaker's other session is drawn too
    with pytest.raises(InputError, match="positives"):
        sample_style_pairs(segs, rng, batch=2, window=50, gap_max=5, min_anchor_gap=100, positives="near")
