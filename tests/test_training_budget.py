"""benchmarks/bench_training_budget.py reads a training budget from constructed checkpoints with known metadata."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest
import torch

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))

import bench_training_budget as budget  # noqa: E402
from dyadbench.errors import InputError  # noqa: E402


def _save(path: Path, meta: dict, config: dict) -> Path:
    torch.save({"model": {"w": torch.zeros(2)}, "config": config, "meta": meta}, path)
    return path


def test_per_epoch_history_is_summed(tmp_path):
    meta = {"model": "timar", "epoch": 2, "step": 20, "seed": 3, "world_size": 1, "command": "dyadbench train timar",
            "settings": {"device": "cpu"},
            "history": [{"epoch": 1, "steps": 10, "seconds": 12.5}, {"epoch": 2, "steps": 20, "seconds": 7.5}]}
    row = budget.read_budget(_save(tmp_path / "t.pt", meta, {"batch_size": 8}), root=tmp_path)
    assert row["checkpoint"] == "t.pt"
    assert (row["model"], row["steps"], row["epochs"], row["seed"]) == ("timar", 20, "2", 3)
    assert row["wall_seconds"] == pytest.approx(20.0)
    assert row["wall_source"].startswith("sum of meta.history")
    assert row["machine"] == "device cpu, world size 1"
    assert row["command"] == "dyadbench train timar"


def test_elapsed_step_history_takes_the_last_entry_and_passes(tmp_path):
    meta = {"model": "dualtalk", "step": 100, "directions": 40, "settings": {"batch_size": 4, "device": "cpu"},
            "history": [{"step": 50, "seconds": 30.0}, {"step": 100, "seconds": 70.0}]}
    row = budget.read_budget(_save(tmp_path / "d.pt", meta, {}), root=tmp_path)
    assert row["wall_seconds"] == pytest.approx(70.0)
    assert row["epochs"].startswith("≈ 10.0 passes")  # 100 steps x 4 / 40 directions
    assert row["command"] == budget.NOT_RECORDED


def test_train_seconds_and_missing_fields(tmp_path):
    meta = {"model": "stygazetalk", "steps": 300, "best_step": 250, "train_seconds": 41.0, "train_windows": 600}
    row = budget.read_budget(_save(tmp_path / "s.pt", meta, {"generator": {"batch": 32}}), root=tmp_path)
    assert (row["steps"], row["best_step"], row["wall_seconds"]) == (300, 250, 41.0)
    assert row["epochs"].startswith("≈ 16.0 passes")  # 300 x 32 / 600
    assert row["machine"] == budget.NOT_RECORDED and row["threads"] is None
    threaded = budget.read_budget(_save(tmp_path / "g.pt", {**meta, "settings": {"device": "cuda", "threads": 2}},
                                        {}), root=tmp_path)
    assert (threaded["machine"], threaded["threads"]) == ("device cuda, 2 torch threads", 2)
    bare = budget.read_budget(_save(tmp_path / "b.pt", {"model": "x"}, {}), root=tmp_path)
    assert (bare["steps"], bare["wall_seconds"], bare["epochs"]) == (None, None, budget.NOT_RECORDED)
    assert bare["wall_source"] == budget.NOT_RECORDED


def test_not_a_checkpoint_names_the_file(tmp_path):
    path = tmp_path / "weights.pt"
    torch.save({"w": torch.zeros(1)}, path)
    with pytest.raises(InputError, match="weights.pt"):
        budget.read_budget(path, root=tmp_path)


def test_marginal_step_seconds():
    assert budget.marginal_step_seconds(10.0, 30.0, 5, 15) == pytest.approx(2.0)
    with pytest.raises(ValueError):
        budget.marginal_step_seconds(1.0, 2.0, 5, 5)


def test_every_shipped_checkpoint_has_a_row():
    rows = [budget.read_budget(p) for p in budget.shipped_checkpoints()]
    assert rows and all(r["steps"] for r in rows)


def test_measurement_is_taken_from_an_earlier_result(tmp_path):
    stage = {"run_batch": 32, "cpu_seconds_at_a": 1.0, "cpu_seconds_at_b": 3.0, "per_step_at_run_batch": 0.2,
             "batch": 32, "per_step": 0.2, "steps": 18000, "hours": 1.0}
    data = {"paper_size": {"StyGazeTalk x": stage}, "measure_steps": [5, 15], "sfms_clips": 16, "sfms_batch": 32}
    old = tmp_path / "old.json"
    old.write_text(json.dumps({"data": data, "markdown": "... (whole measurement 21.0 min wall) ..."}))
    measured, steps, clips, batch, wall = budget.earlier_measurement(old)
    assert measured == {"StyGazeTalk x": stage} and steps == (5, 15) and (clips, batch) == (16, 32)
    assert wall == pytest.approx(1260.0)  # from the markdown of a file written before the data kept it
    old.write_text(json.dumps({"data": {**data, "measure_wall_s": 61.0}}))
    assert budget.earlier_measurement(old)[4] == 61.0
    text = budget._markdown([], measured, 5, 15, 16, 61.0, Path("old.json"))
    assert "1.0 min wall" in text and "earlier measurement in `old.json`" in text and "| StyGazeTalk x |" in text


@pytest.mark.parametrize("content, message", [("{}", "not a result file"),
                                              ('{"data": {"paper_size": null, "measure_steps": null}}',
                                               "no paper-size measurement")])
def test_an_earlier_result_without_a_measurement_is_refused(tmp_path, content, message):
    import click

    bad = tmp_path / "bad.json"
    bad.write_text(content)
    with pytest.raises(click.BadParameter, match=message):
        budget.earlier_measurement(bad)
