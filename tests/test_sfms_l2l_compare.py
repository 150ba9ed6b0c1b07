"""The L2L-line comparison of eval runs: whole clips, and the listener task's frames (`--frames listening`)."""

from __future__ import annotations

import numpy as np
import pytest
from click.testing import CliRunner

from dyadbench.cli import cli
from dyadbench.datasets.base import DyadicClip, Participant
from dyadbench.errors import InputError
from dyadbench.protocol.runner import open_dataset_split
from dyadbench.results import load_result
from dyadbench.scoring import l2l
from dyadbench.scoring.report import ScoreItem
from dyadbench.synth.writers import write_dualtalk_split
from models.sfms import l2l_compare
from models.sfms.l2l_compare import listening_frames, restrict, run_items


def _clip(meta: dict, t: int = 6) -> DyadicClip:
    people = tuple(Participant(name, np.zeros((t, 56)), np.zeros(640 * t)) for name in ("speaker1", "speaker2"))
    return DyadicClip("c0", people, meta=meta)


def test_listening_frames_are_the_agent_silent_and_the_partner_speaking():
    own = np.array([1, 1, 0, 0, 0, 1], bool)
    other = np.array([0, 1, 1, 0, 1, 1], bool)
    clip = _clip({"speaking": {"speaker1": own, "speaker2": other}})
    assert listening_frames(clip, "speaker1").tolist() == [False, False, True, False, True, False]
    assert listening_frames(clip, "speaker2").tolist() == [True, False, False, False, False, False]


@pytest.mark.parametrize("meta", [{}, {"speaking": {"speaker1": np.zeros(6, bool)}},
                                  {"speaking": {"speaker1": np.zeros(5, bool), "speaker2": np.zeros(5, bool)}}])
def test_listening_frames_without_usable_masks_is_a_clear_error(meta):
    with pytest.raises(InputError, match="c0.*speaking"):
        listening_frames(_clip(meta), "speaker1")


def test_restrict_cuts_every_array_to_the_mask_and_leaves_out_items_under_two_frames():
    a = np.arange(5 * 56, dtype=float).reshape(5, 56)
    items = [ScoreItem("x_speaker1", a, a + 1, a + 2), ScoreItem("y_speaker1", a, a, a)]
    mask = np.array([1, 0, 1, 1, 0], bool)
    out = restrict(items, [mask, np.array([0, 0, 1, 0, 0], bool)])
    assert [i.stem for i in out] == ["x_speaker1"]
    for got, full in zip((out[0].pred, out[0].gt, out[0].partner), (a, a + 1, a + 2)):
        assert np.array_equal(got, full[[0, 2, 3]])
    with pytest.raises(InputError, match="runs/x.*2 or more frames"):
        restrict(items[1:], [mask * False], "runs/x")


@pytest.fixture(scope="module")
def mime_run(tmp_path_factory):
    """A DualTalk-layout root (its clips carry energy-VAD speaking masks) and a mime eval run on it."""
    root = tmp_path_factory.mktemp("dualtalk")
    for split in ("train", "test"):
        write_dualtalk_split(root, split=split, clips=2, seed=0, progress=False)
    run = root / "run"
    result = CliRunner().invoke(cli, ["eval", "--model", "mime", "--data", str(root), "--split", "test",
                                      "--context", "2", "--out", str(run)], catch_exceptions=False)
    assert result.exit_code == 0, result.output
    return root, run


def test_listening_items_score_exactly_the_masked_frames(mime_run):
    root, run = mime_run
    result = load_result(run / "result.json")
    items, masks = run_items(result, run, data=root, frames="listening")
    whole, ones = run_items(result, run, data=root)
    source = open_dataset_split("dualtalk", root, "test")
    assert all(m.all() for m in ones) and len(items) == len(whole) == 4
    for item, mask in zip(items, masks):
        clip_id, _, agent = item.stem.rpartition("_")
        assert np.array_equal(mask, listening_frames(source.load(clip_id), agent)[:len(item.pred)])
        assert 0 < mask.sum() < len(mask)
    kept = restrict(items, masks)
    expected = l2l.score_arrays([ScoreItem(i.stem, i.pred[m], i.gt[m], i.partner[m]) for i, m in zip(items, masks)],
                                seed=0).metrics
    assert l2l.score_arrays(kept, seed=0).metrics == expected
    assert expected["fd_exp"] != l2l.score_arrays(whole, seed=0).metrics["fd_exp"]


def test_compare_command_writes_the_listening_table(mime_run, tmp_path):
    root, run = mime_run
    out = tmp_path / "t.md"
    result = CliRunner().invoke(l2l_compare.main, [str(run), "--data", str(root), "--frames", "listening",
                                                   "--out", str(out)], catch_exceptions=False)
    assert result.exit_code == 0, result.output
    text = out.read_text()
    assert "--frames listening" in text and "| mime | 2 | 4 |" in text


def test_paired_table_is_the_mean_and_standard_error_of_per_sequence_differences():
    def rows(values, clips=("a", "b", "c")):
        return [{"clip": c, **{k: v for k in l2l_compare.COLUMNS}} for c, v in zip(clips, values)]

    text = l2l_compare.paired_table([("first", rows([1.0, 2.0, 3.0])), ("other", rows([2.0, 2.0, 5.0]))])
    # d = (-1, 0, -2): mean -1, std (ddof 1) 1, s.e. 1/sqrt(3) = 0.577; 2 of 3 lower
    assert "| other | 3 | -1 ± 0.58 (2 lower) |" in text
    with pytest.raises(InputError, match="shares 1 scored sequences"):
        l2l_compare.paired_table([("first", rows([1.0, 2.0])), ("other", rows([1.0, 2.0], clips=("b", "z")))])


def test_compare_command_pairs_runs_over_the_same_sequences(mime_run, tmp_path):
    root, run = mime_run
    result = CliRunner().invoke(l2l_compare.main, [str(run), str(run), "--data", str(root), "--paired"],
                                catch_exceptions=False)
    assert result.exit_code == 0, result.output
    assert "| mime | 4 | +0 ± 0 (0 lower) |" in result.output  # a run against itself: no difference
