"""``evaluate`` scores a split without holding its predictions: the DualTalk/TIMAR suite reads each direction
back (:class:`~dyadbench.scoring.stored.StoredItem`) when it scores it, with the numbers of the in-memory path."""

from __future__ import annotations

import tracemalloc

import numpy as np
import pytest

from dyadbench.protocol import runner
from dyadbench.protocol.config import ProtocolConfig
from dyadbench.protocol.runner import evaluate, read_back
from dyadbench.scoring import dualtalk
from dyadbench.scoring.stored import StoredItem, streams_items
from tests.protocol_clips import isolated_cache, make_source  # noqa: F401

SECONDS = 12.0  # 300 frames at 25 fps: a (300, 56) float32 prediction is 67,200 bytes


@pytest.fixture
def in_memory(monkeypatch):
    """The path before streaming: every ScoreItem (with its prediction array) held until scoring."""
    monkeypatch.setattr(runner, "streams_items", lambda suite: False)


def _peak_growth(n: int) -> int:
    """Peak bytes traced during ``evaluate`` of mime on ``n`` clips, above the traced bytes at its start."""
    source = make_source(n, seconds=SECONDS, seed=4)
    runner._SCORE_MEMO.clear()
    tracemalloc.start()
    try:
        base = tracemalloc.get_traced_memory()[0]
        evaluate("mime", source, ProtocolConfig(context=0, seed=1), progress=False)
        return tracemalloc.get_traced_memory()[1] - base
    finally:
        tracemalloc.stop()


def test_dualtalk_suite_streams_items():
    assert streams_items("dualtalk") and not streams_items("l2l")


def test_peak_memory_does_not_grow_with_the_held_predictions(request):
    # 20 more clips = 40 more predictions of 67,200 bytes: 2.69 MB that the in-memory path holds at once
    held = 20 * 2 * 300 * 56 * 4
    streamed = _peak_growth(24) - _peak_growth(4)
    request.getfixturevalue("in_memory")
    whole = _peak_growth(24) - _peak_growth(4)
    assert whole >= 0.9 * held, (whole, held)  # the measurement sees the held predictions ...
    assert streamed < 0.25 * held, (streamed, held)  # ... and streaming does not hold them


def test_streamed_scores_equal_in_memory_scores(tmp_path):
    source = make_source(5, seconds=6.0, seed=2)
    config = ProtocolConfig(context=1, seed=5)
    runner._SCORE_MEMO.clear()
    result = evaluate("mime", source, config, predictions_dir=tmp_path / "p", progress=False)
    items = [read_back(source, clip_id, agent, tmp_path / "p" / f"{clip_id}_{agent}.npy", False)
             for clip_id in source.clip_ids() for agent in ("speaker1", "speaker2")]
    # the same arrays as the streamed ones: mime copies the partner's motion turn by turn
    for item in items:
        np.testing.assert_array_equal(item.pred, item.partner[: len(item.pred)])
    report = dualtalk.score_arrays(items, seed=5)
    assert result.metrics == report.metrics and result.per_clip == report.per_item
    assert result.uncertainty == report.uncertainty
    # the memo still recognises byte-identical predictions (digest taken while streaming)
    again = evaluate("mime", source, config, progress=False)
    assert any("scores reused" in note for note in again.notes) and again.metrics == result.metrics


def test_stored_item_read_back_as_another_item_is_refused():
    stored = StoredItem("c000_speaker1", False, lambda: dualtalk.ScoreItem(
        "c000_speaker1", np.zeros((2, 56)), np.zeros((2, 56)), np.zeros((2, 56))))
    with pytest.raises(Exception, match="read back as 'c000_speaker1' \\(partner present\\)"):
        stored.load()
