"""`dyadbench score` writes the typed result `eval` writes, so `leaderboard` ranks predictions made anywhere;
files `score` wrote before (``results.json``) still load."""

import json
import math

import numpy as np
import pandas as pd
import pytest

from dyadbench.datasets.dualtalk_files import write_gt_npz
from dyadbench.errors import InputError
from dyadbench.results import EXTERNAL, load_result
from tests.cli_run import run

T = 90


@pytest.fixture()
def folders(tmp_path):
    """A two-clip DualTalk split and two prediction folders: `good` (ground truth + small noise), `flat`
    (every frame the clip's mean: worse FD exp)."""
    rng = np.random.default_rng(5)
    gt, good, flat = tmp_path / "gt", tmp_path / "good", tmp_path / "flat"
    for d in (gt, good, flat):
        d.mkdir()
    for clip in ("c1", "c2"):
        for k in (1, 2):
            stem = f"{clip}_speaker{k}"
            motion = np.cumsum(rng.normal(size=(T, 56)) * 0.05, axis=0)
            write_gt_npz(gt / f"{stem}.npz", motion)
            np.save(good / f"{stem}.npy", (motion + 0.01 * rng.normal(size=motion.shape)).astype(np.float32))
            np.save(flat / f"{stem}.npy", np.repeat(motion.mean(0, keepdims=True), T, axis=0).astype(np.float32))
    return gt, good, flat


def test_score_results_are_ranked_by_leaderboard(folders, tmp_path, capsys):
    gt, good, flat = folders
    for pred, name in ((good, "model-a"), (flat, None)):
        code, _, err = run(capsys, "score", pred, "--gt", gt, "--out", tmp_path / "res" / pred.name,
                           *(["--model", name] if name else []))
        assert code == 0, err
    result = load_result(tmp_path / "res" / "good" / "result.json")
    assert result.external and result.protocol.name == EXTERNAL and result.model.name == "model-a"
    assert result.data.items == 4 and result.data.clips == 2 and result.data.split == "gt"
    assert result.protocol.context is None and result.protocol.cfg_scale is None and result.timing.turns == 0
    assert len(result.per_clip) == 4 and result.uncertainty["fd_exp"]["se"] >= 0
    code, out, err = run(capsys, "leaderboard", tmp_path / "res", "--out", tmp_path / "lb", "--no-paper", "--latex")
    assert code == 0, err
    assert "predictions made outside dyadbench" not in err and "2 of 2 result rows unverified" in err
    wide = pd.read_csv(tmp_path / "lb" / "dualtalk_wide.csv", keep_default_na=False)
    assert list(wide["model"]) == ["model-a", "flat"]  # default name: the prediction folder's
    assert list(wide["rank"]) == [1, 2] and set(wide["protocol"]) == {EXTERNAL}
    assert set(wide["rank_group"]) == {"4 items / 2 clips"} and set(wide["context"]) == {""}
    assert "model-a" in (tmp_path / "lb" / "dualtalk_wide.tex").read_text()


def test_eval_folder_predictions_are_named_by_the_run(folders, tmp_path, capsys):
    gt, good, _ = folders
    run_dir = tmp_path / "runs" / "my-run"
    run_dir.mkdir(parents=True)
    good.rename(run_dir / "predictions")
    assert run(capsys, "score", run_dir / "predictions", "--gt", gt, "--out", tmp_path / "s")[0] == 0
    assert load_result(tmp_path / "s" / "result.json").model.name == "my-run"


def _old_results_json(folder, gt):
    """A results.json in the schema `score` wrote before it wrote typed results, written out by hand,
    with its per_clip.csv."""
    folder.mkdir()
    metrics = {"fd_exp": 0.5, "mse_jaw": 0.002, "pfd_exp": None}
    (folder / "results.json").write_text(json.dumps({
        "suite": "dualtalk", "metrics": metrics, "scaled": {"fd_exp": 0.5, "mse_jaw": 2.0, "pfd_exp": None},
        "excluded": [], "coverage": {"expected": 2, "scored": 2, "missing": [], "extra": []},
        "config": {"suite": "dualtalk", "pred": "preds", "gt": str(gt), "seed": 3},
        "notes": [], "uncertainty": {}, "uncertainty_method": {}, "dyadbench_version": "0.1.0",
        "n_scored": 2, "scaling": {"fd_exp": 1.0, "mse_jaw": 1000.0, "pfd_exp": 1.0}}))
    (folder / "per_clip.csv").write_text("clip,fd_exp,mse_jaw,pfd_exp\n"
                                         "dlg_speaker1,0.4,0.001,\ndlg_speaker2,0.6,0.003,\n")


def test_an_old_score_results_json_loads_and_is_ranked(folders, tmp_path, capsys):
    gt, _, _ = folders
    old = tmp_path / "res" / "old-model"
    (tmp_path / "res").mkdir()
    _old_results_json(old, gt)
    result = load_result(old / "results.json")
    assert result.external and result.model.name == "old-model" and result.protocol.seed == 3
    assert result.metrics["fd_exp"] == 0.5 and math.isnan(result.metrics["pfd_exp"])
    assert result.data.items == 2 and result.data.clips == 1 and result.data.split == "gt"
    assert [r["clip"] for r in result.per_clip] == ["dlg_speaker1", "dlg_speaker2"]
    assert result.per_clip[1]["fd_exp"] == 0.6 and math.isnan(result.per_clip[0]["pfd_exp"])
    assert result.environment == {"dyadbench": "0.1.0"}
    (old / "per_clip.csv").unlink()  # without its per-clip file: the recorded counts
    assert load_result(old / "results.json").data.items == 2
    code, _, err = run(capsys, "leaderboard", tmp_path / "res", "--out", tmp_path / "lb", "--no-paper")
    assert code == 0, err
    wide = pd.read_csv(tmp_path / "lb" / "dualtalk_wide.csv")
    assert list(wide["model"]) == ["old-model (seed3)"] and wide["fd_exp"].iloc[0] == 0.5  # scoring seed 3


def test_a_malformed_old_results_json_is_named(tmp_path):
    folder = tmp_path / "bad"
    folder.mkdir()
    (folder / "results.json").write_text(json.dumps({"suite": "dualtalk", "metrics": {}, "n_scored": 1}))
    with pytest.raises(InputError, match="results.json: field 'config' missing"):
        load_result(folder / "results.json")
