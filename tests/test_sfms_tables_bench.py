"""benchmarks/bench_sfms_tables.py names what its table mixes: runs trained off the CPU, and rows whose ratio
is not to a dynamic arm of their own k."""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))

import bench_sfms_tables as tables  # noqa: E402


def test_runs_trained_off_the_cpu_are_named():
    channel, static = tables.Arm("channel", 7, (8, 6, 5)), tables.Arm("static", 3, (8, 6, 5))
    runs = {channel: [{"seed": 0, "device": "cuda"}, {"seed": 1, "device": "cpu"}],
            static: [{"seed": 0}, {"seed": 1}]}  # runs recorded before the device was kept: the CPU
    note = tables.off_cpu_note(runs)
    assert note.startswith(" Trained on cuda") and "dynamic per-channel k = 7 seed 0." in note
    assert "seed 1" not in note and "static" not in note
    assert tables.off_cpu_note({static: [{"seed": 0, "device": "cpu"}]}) == ""


def test_per_channel_counts_without_a_dynamic_arm_are_named():
    assert tables.other_k_note([3, 7, 10], [3, 7]) == ", per-channel k = 10"
    assert tables.other_k_note([3], [3, 7]) == ""
