"""Seamless Interaction: discovery in both layouts, pairing problems, validity masking, resampling, eval."""

from __future__ import annotations

import numpy as np
import pytest
from click.testing import CliRunner

from dyadbench.cli import cli
from dyadbench.datasets.seamless import SEAMLESS, SeamlessSplit, open_split, read_motion, validate_folder
from dyadbench.datasets.seamless_audio import to_16k
from dyadbench.metrics import dualtalk
from dyadbench.metrics.seamless import item_metrics
from dyadbench.results import load_result
from dyadbench.synth.seamless_writer import write_seamless_split


@pytest.fixture(scope="module")
def root(tmp_path_factory):
    out = tmp_path_factory.mktemp("seamless")
    for split in ("test", "train"):
        write_seamless_split(out, split=split, clips=10, progress=False)
    return out


def test_discovery_both_layouts_and_skips(root):
    source = open_split(root, "improvised/test")
    ids = source.clip_ids()
    # dyads 7 (second bundle empty) and 8 (vendor V01, no movement) are skipped; 9 is per-modality
    assert len(ids) == 8 and "V00_S2000_I00000009" in ids
    assert not any(i.endswith(("I00000007", "I00000008")) for i in ids)
    reasons = " ".join(s["reason"] for s in source.skipped)
    assert "V00_S2000_I00000007_P20015.npz: empty bundle (0 frames)" in reasons
    assert "no movement features" in reasons
    clip = source.load("V00_S2000_I00000009")  # per-modality layout
    assert clip.fps == 30.0 and clip.sample_rate == 16_000
    assert clip.participants[0].motion.shape[1] == SEAMLESS.dim
    assert clip.participants[0].audio.shape[0] == pytest.approx(clip.num_frames / 30 * 16_000, abs=2)


def test_pairing_errors_reported(root, tmp_path):
    import shutil
    copy = tmp_path / "copy"
    shutil.copytree(root, copy)
    lone = next((copy / "improvised" / "test").rglob("V00_S2000_I00000000_P20001.npz"))
    lone.unlink()
    (lone.parent / "not_a_stem.npz").write_bytes(lone.with_suffix(".wav").read_bytes()[:0])
    report = validate_folder(copy, progress=False)
    text = report.summary()
    assert "V00_S2000_I00000000: skipped: 1 usable participant(s) of 1" in text
    assert "not_a_stem.npz" in text
    assert "dyad(s) skipped" in text


def _motion(rng, frames, valid):
    m = np.zeros((frames, SEAMLESS.dim))
    m[:, :-1] = rng.standard_normal((frames, SEAMLESS.dim - 1))
    m[~valid, :-1] = 0.0
    m[:, -1] = valid
    return m


def test_invalid_blocks_excluded_from_every_metric():
    rng = np.random.default_rng(0)
    valid = np.ones(240, bool)
    valid[60:120] = False  # one zero-filled 2-s block
    gt, partner = _motion(rng, 240, valid), _motion(rng, 240, np.ones(240, bool))
    pred = gt.copy()
    pred[~valid, :-1] = 5.0  # whatever a model emits there must not count
    out = item_metrics(pred, gt, partner, SEAMLESS, seed=0)
    # independent: FD over the 180 valid frames only is 0 (prediction = ground truth there)
    assert out["fd_expression"] == pytest.approx(0.0, abs=1e-6) and out["mse_expression"] == 0.0
    assert out["frames_excluded"] == 60 and out["frames_scored"] == 180
    # scoring the invalid frames would change FD
    assert dualtalk.fd(pred[:, :128], gt[:, :128]) > 1.0


def test_resampler_sine_and_aliasing():
    t = np.arange(48_000) / 48_000
    tone = to_16k(0.5 * np.sin(2 * np.pi * 1000 * t))
    assert len(tone) == 16_000
    middle = tone[1000:-1000]
    assert np.abs(middle).max() == pytest.approx(0.5, rel=0.01)
    spectrum = np.abs(np.fft.rfft(tone))
    assert np.argmax(spectrum) == 1000  # 1 Hz bins over one second
    alias = to_16k(0.5 * np.sin(2 * np.pi * 10_000 * t))[1000:-1000]
    assert np.sqrt(np.mean(alias ** 2)) < 0.01 * 0.5 / np.sqrt(2)


def test_eval_mime_and_leaderboard_row_and_reference_refusal(root, tmp_path):
    runner = CliRunner()
    out = tmp_path / "run"
    result = runner.invoke(cli, ["eval", "--dataset", "seamless", "--data", str(root), "--model", "mime",
                                  "--split", "test", "--out", str(out)])
    assert result.exit_code == 0, result.output
    recorded = load_result(out / "result.json")
    # dyads 7 (empty bundle) and 8 (no movement features) of the 10 are skipped, with the count in the notes
    assert recorded.data.clips == 8
    assert any(n.startswith("2 dyad(s) of the split skipped by the reader") and "I00000007_P20015.npz: empty "
               "bundle" in n for n in recorded.notes), recorded.notes
    board = runner.invoke(cli, ["leaderboard", str(out / "result.json"), "--out", str(tmp_path / "boards"), "--no-paper"])
    assert board.exit_code == 0, board.output
    assert "mime" in board.output
    # timar-stream ships no seamless checkpoint: its FLAME one is refused, naming the file (timar: its own
    # seamless checkpoint, tests/test_timar_seamless.py)
    refused = runner.invoke(cli, ["eval", "--dataset", "seamless", "--data", str(root), "--model", "timar-stream",
                                   "--split", "test", "--out", str(tmp_path / "timar-stream")])
    assert refused.exit_code != 0
    assert ("timar-stream-tiny-v2.pt: this timar-stream checkpoint generates flame56 motion (56 dims at 25 fps); "
            "the split is seamless") in str(refused.exception)


def test_score_cli_seamless_split_result_and_leaderboard(root, tmp_path):
    pred = tmp_path / "pred"
    pred.mkdir()
    pairs = SeamlessSplit.open(root, "improvised/test").pairs
    for first, second in pairs.values():  # each agent predicted by its partner's features (mime)
        for agent, partner in ((first, second), (second, first)):
            np.save(pred / f"{agent.stem}.npy", read_motion(partner))
    runner = CliRunner()
    out = tmp_path / "scored"
    result = runner.invoke(cli, ["score", str(pred), "--gt", str(root), "--suite", "seamless", "--split",
                                  "improvised/test", "--model", "partner-copy", "--out", str(out)])
    assert result.exit_code == 0, result.output
    recorded = load_result(out / "result.json")
    assert recorded.suite == "seamless" and recorded.data.split == "improvised/test"
    assert recorded.model.name == "partner-copy" and recorded.data.items == 2 * len(pairs) == 16
    assert any("2 dyad(s) of the split skipped" in n for n in recorded.notes)
    board = runner.invoke(cli, ["leaderboard", str(out), "--out", str(tmp_path / "boards"), "--no-paper"])
    assert board.exit_code == 0, board.output
    long = (tmp_path / "boards" / "long.csv").read_text()
    assert any(line.startswith("dyadbench,") and ",partner-copy," in line for line in long.splitlines()), long[:500]
    train_split = runner.invoke(cli, ["score", str(pred), "--gt", str(root), "--suite", "seamless", "--split",
                                       "improvised/train"])
    assert train_split.exit_code != 0  # --split reaches the suite: no prediction names a train participant
