"""SimWithGT split into its FixRatio and CompScore gaps (dyadbench.metrics.sim_terms), against hand-derived values."""

from __future__ import annotations

import math

import pytest

from dyadbench.errors import InputError
from dyadbench.metrics.sim_terms import sim_terms


def test_hand_derived_example():
    # GT (0.60, -0.33), prediction (0.90, -0.20): gaps 0.30 and 0.13
    t = sim_terms(0.60, -0.33, 0.90, -0.20)
    assert t.fix_gap == pytest.approx(0.30)
    assert t.comp_gap == pytest.approx(0.13)
    assert t.sim == pytest.approx(1 - 0.43)
    assert t.sim_fix_gt == pytest.approx(0.87)  # FixRatio set to GT's: only the CompScore gap is left
    assert t.sim_comp_gt == pytest.approx(0.70)  # CompScore set to GT's: only the FixRatio gap is left
    assert t.limiting == "FixRatio"
    assert t.as_dict()["limiting"] == "FixRatio"


def test_compscore_limits_when_its_gap_is_larger():
    # prediction below GT in FixRatio, far in CompScore: |0.55 - 0.60| = 0.05, |0.10 - (-0.30)| = 0.40
    t = sim_terms(0.60, -0.30, 0.55, 0.10)
    assert (t.fix_gap, t.comp_gap) == (pytest.approx(0.05), pytest.approx(0.40))
    assert t.sim == pytest.approx(0.55)
    assert t.limiting == "CompScore"


def test_reproduces_the_papers_best_simscore():
    # paper Table 3: GT 61.13 % / -0.3366, SE-64-vel 67.33 % / -0.3100, SimScore 0.9114
    t = sim_terms(0.6113, -0.3366, 0.6733, -0.3100)
    assert t.sim == pytest.approx(0.9114, abs=5e-5)
    assert t.fix_gap == pytest.approx(0.062, abs=1e-9)
    assert t.comp_gap == pytest.approx(0.0266, abs=1e-9)
    assert t.sim_fix_gt == pytest.approx(1 - 0.0266, abs=1e-9)


def test_ground_truth_scores_one_and_ties():
    t = sim_terms(0.6, -0.3, 0.6, -0.3)
    assert (t.sim, t.sim_fix_gt, t.sim_comp_gt, t.limiting) == (1.0, 1.0, 1.0, "tie")


def test_non_finite_input_is_an_error():
    with pytest.raises(InputError, match="fix_pred"):
        sim_terms(0.6, -0.3, math.nan, -0.3)
