"""The seed sweep of bench_stygazetalk_variants.py: seed parsing, mean ± s.e. (benchmarks/seed_stats.py) and the SimWithGT split."""

from __future__ import annotations

import math
import sys
from pathlib import Path

import click
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))

import seed_stats  # noqa: E402
import stygazetalk_seed_sweep as sweep  # noqa: E402


def test_parse_seeds():
    assert sweep.parse_seeds("0,1, 2") == [0, 1, 2]
    for bad in ("0", "0,0", "a,b", "-1,2"):
        with pytest.raises(click.BadParameter):
            sweep.parse_seeds(bad)


def test_mean_se_hand_values():
    m, se = seed_stats.mean_se([1.0, 2.0, 3.0])  # sample std 1, s.e. 1 / sqrt(3)
    assert m == pytest.approx(2.0) and se == pytest.approx(1 / math.sqrt(3))
    m1, se1 = seed_stats.mean_se([4.0])
    assert m1 == 4.0 and math.isnan(se1)


def test_decompose_per_seed_against_gt():
    gt = {"fix_ratio": 0.6, "comp_score": -0.3}
    runs = [{"fix_ratio": 0.9, "comp_score": -0.2}, {"fix_ratio": 0.8, "comp_score": -0.3}]
    d = sweep.decompose(runs, gt)
    # seed 1: gaps 0.3 / 0.1 -> sim 0.6; seed 2: gaps 0.2 / 0.0 -> sim 0.8
    assert d["sim"][0] == pytest.approx(0.7)
    assert d["fix_gap"][0] == pytest.approx(0.25)
    assert d["comp_gap"][0] == pytest.approx(0.05)
    assert d["sim_fix_gt"][0] == pytest.approx(0.95)  # 1 - comp gap, averaged
    assert d["sim_comp_gt"][0] == pytest.approx(0.75)  # 1 - fix gap, averaged
    assert d["limiting"] == ["FixRatio"]


def test_rows_cover_the_paper_variants_and_the_shipped_configuration():
    labels = [label for label, _, _ in sweep.ROWS]
    assert labels[:5] == ["Base", "SE-32", "SE-64", "SE-64-VEL", "TFM-SE-64"]
    assert "MPGW-sim" in labels and sweep.SHIPPED_LABEL in labels
