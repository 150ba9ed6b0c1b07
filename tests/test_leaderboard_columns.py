"""Every suite's one column declaration is what results, long.csv, the wide tables and LaTeX use; rows are
ranked only against rows scored on the same predictions.

Expected directions and scales are written out by hand from the papers' tables (DualTalk/TIMAR: FD jaw
×10³, MSE exp ×10, rPCC exp ×10²; StyGazeTalk Table 3: fixation and saccade in %; SimScore higher is
better) and, for L2L's jaw and pose (~1e-3 rotations, which no public L2L table prints), dyadbench's ×10³,
never read back from the declaration under test.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from dyadbench.cli.leaderboard import PAPER_ROWS
from dyadbench.leaderboard import latex_table, long_table, paper_rows, wide_table
from dyadbench.results import DataRecord, EvalResult, ModelRecord, ProtocolRecord, TimingRecord
from dyadbench.scoring import dualtalk, gaze, l2l
from dyadbench.scoring.report import ScoreItem, ScoreReport

# key -> (higher_is_better, scale), by hand from the papers' tables
EXPECTED = {
    "dualtalk": {"fd_exp": (False, 1.0), "fd_jaw": (False, 1e3), "fd_pose": (False, 1e2), "mse_exp": (False, 10.0),
                 "rpcc_exp": (False, 1e2), "rpcc_jaw": (False, 10.0), "sid_exp": (True, 1.0),
                 "var_pred_exp": (None, 1.0), "div_gt_pose": (None, 1.0)},
    "gaze": {"mae_all": (False, 1.0), "bas_all": (True, 1.0), "sim_gt": (True, 1.0), "fix_ratio": (None, 100.0),
             "saccade_ratio": (None, 100.0), "gt_fix_ratio": (None, 100.0), "gt_saccade_ratio": (None, 100.0),
             "gt_comp_score": (None, 1.0), "gt_bas_all": (None, 1.0), "bas_shuffled_all": (None, 1.0),
             "bas_a2m_all": (True, 1.0)},
    "l2l": {"l2_exp": (False, 1.0), "l2_jaw": (False, 1e3), "fd_pose": (False, 1e3), "si_exp": (True, 1.0),
            "si_jaw": (True, 1.0), "si_gt_exp": (None, 1.0), "var_gt_jaw": (None, 1e3), "rpcc_pose": (False, 1.0)},
    "react": {"FRCorr": (True, 1.0), "FRDist": (False, 1.0), "FRDiv": (True, 1.0), "FRSyn": (False, 1.0)},
}
#: the wide tables' first columns, in the papers' order (StyGazeTalk Table 2, then Table 3)
FIRST_COLUMNS = {"dualtalk": ["fd_exp", "fd_jaw", "fd_pose", "pfd_exp"],
                 "gaze": ["mae_all", "vel_all", "mee_all", "style_ce", "bas_all", "mae_gaze"],
                 "l2l": ["l2_exp", "l2_pose", "l2_jaw", "fd_exp"]}


def _flame_items(n: int, frames: int = 60, seed: int = 0) -> list[ScoreItem]:
    r = np.random.default_rng(seed)
    return [ScoreItem(stem=f"c{i}_speaker1", pred=r.normal(size=(frames, 56)), gt=r.normal(size=(frames, 56)),
                      partner=r.normal(size=(frames, 56))) for i in range(n)]


def _gaze_items(n: int, frames: int = 150, seed: int = 0) -> list[ScoreItem]:
    r = np.random.default_rng(seed)
    walk = lambda: np.cumsum(r.normal(scale=0.5, size=(frames, 7)), axis=0)  # noqa: E731
    return [ScoreItem(stem=f"s{i}_subject", pred=walk(), gt=walk()) for i in range(n)]


def _fresh(suite: str) -> ScoreReport:
    if suite == "dualtalk":
        return dualtalk.score_arrays(_flame_items(2))
    if suite == "l2l":
        return l2l.score_arrays(_flame_items(3))
    if suite == "gaze":
        return gaze.score_arrays(_gaze_items(2))
    return ScoreReport(suite="react", metrics={"FRCorr": 0.5, "FRDist": 80.0, "FRDiv": 0.1, "FRSyn": 40.0},
                       per_item=[])


@pytest.mark.parametrize("suite", sorted(EXPECTED))
def test_a_fresh_result_scales_every_key_as_declared(suite):
    report = _fresh(suite)
    d = report.to_dict()
    for key, (higher, scale) in EXPECTED[suite].items():
        if key not in report.metrics:
            continue
        raw = report.metrics[key]
        assert d["scaling"][key] == scale, key
        assert d["scaled"][key] == pytest.approx(raw * scale, nan_ok=True), key
        if "higher_is_better" in report.config:
            assert report.config["higher_is_better"][key] is higher, key
    assert set(d["scaling"]) == set(report.metrics)  # every key, printed or not (gaze gt_fix_ratio included)
    present = [k for k in EXPECTED[suite] if k in report.metrics]
    assert len(present) >= min(3, len(EXPECTED[suite])), present


def _result(tmp_path, suite: str, model: str, metrics: dict, *, items: int = 8, clips: int = 4,
            digest: str | None = None, context: int = 0, scaled: dict | None = None, scaling: dict | None = None,
            oracle: bool = False, name: str | None = None) -> None:
    """A hand-made result file (as ``dyadbench eval`` writes them) of ``metrics`` (raw values)."""
    EvalResult(
        model=ModelRecord(model, "1", None, None, oracle, "flame56", {}),
        data=DataRecord("synthetic", "test", None, clips=clips, items=items, digest=digest),
        protocol=ProtocolRecord("streaming", 1.0, context, "truncate", "masked", 1.0, 0),
        suite=suite, metrics=metrics, scaled=scaled if scaled is not None else dict(metrics),
        scaling=scaling if scaling is not None else {k: 1.0 for k in metrics}, per_clip=[],
        timing=TimingRecord(1.0, 1.0, 1, 1.0)).write(tmp_path / f"{name or model}.json")


@pytest.mark.parametrize("suite", sorted(EXPECTED))
def test_long_and_wide_tables_use_the_declared_direction_and_scale(tmp_path, suite):
    raw = {key: 0.25 + i for i, key in enumerate(EXPECTED[suite])}
    _result(tmp_path, suite, "a", raw)  # recorded scaled/scaling deliberately wrong (all 1)
    long = long_table([tmp_path])
    for key, (higher, scale) in EXPECTED[suite].items():
        row = long[long["metric"] == key].iloc[0]
        assert row["raw"] == raw[key] and row["scale"] == scale and row["scaled"] == raw[key] * scale, key
        assert (pd.isna(row["higher_is_better"]) if higher is None else row["higher_is_better"] == higher), key
    wide = wide_table(long, suite)
    if suite in FIRST_COLUMNS:
        metrics = list(wide.columns[list(wide.columns).index("items") + 1:])
        assert metrics[:len(FIRST_COLUMNS[suite])] == FIRST_COLUMNS[suite]
    for key, (_, scale) in EXPECTED[suite].items():
        if key in wide:
            assert wide[key].iloc[0] == raw[key] * scale, key


def test_old_gaze_results_show_ratios_in_percent(tmp_path):
    # written before the scale was declared once: scaled x100 but scaling 1 for the ground truth's ratios
    metrics = {"sim_gt": 0.9114, "fix_ratio": 0.6733, "gt_fix_ratio": 0.6113, "gt_saccade_ratio": 0.3887}
    _result(tmp_path, "gaze", "old", metrics, scaled={k: v * (1 if k == "sim_gt" else 100) for k, v in metrics.items()},
            scaling={"fix_ratio": 100.0})
    long = long_table([tmp_path]).set_index("metric")
    assert long.loc["gt_fix_ratio", "scale"] == 100 and long.loc["gt_fix_ratio", "scaled"] == pytest.approx(61.13)
    assert long.loc["gt_saccade_ratio", "scaled"] == pytest.approx(38.87)
    tex = latex_table(wide_table(long.reset_index(), "gaze"), "gaze")
    lines = tex.splitlines()
    header = lines[2].removesuffix(r" \\").split(" & ")
    truth = next(line for line in lines if line.startswith(r"\emph{ground truth}")).removesuffix(r" \\").split(" & ")
    # the ground truth's own ratios are its row under the prediction's columns, never a column of their own
    assert truth[header.index(r"fixation (\%)")] == "61.13" and truth[header.index(r"saccade (\%)")] == "38.87"
    assert r"SimScore$\uparrow$" in header and not [h for h in header if h.startswith("GT")]


def test_gaze_ranks_by_simscore_descending(tmp_path):
    # SimScore order a > c > b; the alphabetically first column (bas_a2m_all) and MAE say otherwise
    for model, sim, bas_a2m, mae in (("a", 0.91, 0.10, 9.0), ("b", 0.63, 0.40, 1.0), ("c", 0.82, 0.20, 5.0)):
        _result(tmp_path, "gaze", model, {"sim_gt": sim, "bas_a2m_all": bas_a2m, "mae_all": mae})
    _result(tmp_path, "gaze", "static", {"sim_gt": 0.29, "mae_all": 2.0})  # no BAS at all: ranked too
    _result(tmp_path, "gaze", "copy", {"sim_gt": 1.0, "mae_all": 0.0}, oracle=True)
    wide = wide_table(long_table([tmp_path]), "gaze")
    assert list(wide["model"]) == ["a", "c", "b", "static", "copy"]
    assert wide["rank"].tolist()[:4] == [1, 2, 3, 4] and pd.isna(wide["rank"].iloc[4])
    tex = latex_table(wide, "gaze")
    assert r"\textbf{0.91}" in next(line for line in tex.splitlines() if line.startswith("a &"))


def test_rows_scored_on_different_predictions_are_never_ranked_together(tmp_path):
    # 1066 items / 533 clips: two recorded data digests disagree, so each is its own set and the rows that
    # record none form a third; 40 items / 20 clips: one recorded digest, nothing contradicts it, one set.
    runs = [("full-a", 1066, 533, None, 5.0), ("full-b", 1066, 533, None, 4.0), ("first-20", 40, 20, None, 1.0),
            ("other-20", 40, 20, None, 2.0), ("digested", 1066, 533, "abcdef0123456789", 0.5),
            ("digested-2", 1066, 533, "0123456789abcdef", 0.7), ("first-20-digested", 40, 20, "fedcba98", 1.5),
            ("oracle", 1066, 533, None, 0.0)]
    for model, items, clips, digest, fd in runs:
        _result(tmp_path, "dualtalk", model, {"fd_exp": fd}, items=items, clips=clips, digest=digest,
                oracle=model == "oracle")
    long = pd.concat([long_table([tmp_path]), paper_rows(PAPER_ROWS)], ignore_index=True)
    wide = wide_table(long)
    ours = wide[wide["source"] == "dyadbench"].set_index("model")
    unrecorded = "1066 items / 533 clips, data unrecorded"
    assert ours["rank_group"].to_dict() == {
        "full-b": unrecorded, "full-a": unrecorded, "oracle": unrecorded,
        "digested": "1066 items / 533 clips, data abcdef012345",
        "digested-2": "1066 items / 533 clips, data 0123456789ab",
        "first-20": "40 items / 20 clips", "other-20": "40 items / 20 clips",
        "first-20-digested": "40 items / 20 clips"}
    ranks = ours["rank"].to_dict()
    order = ("full-b", "full-a", "digested", "digested-2", "first-20", "first-20-digested", "other-20")
    assert tuple(ranks[m] for m in order) == (1, 2, 1, 1, 1, 2, 3)
    assert pd.isna(ranks["oracle"])
    for _, group in wide[wide["rank"].notna()].groupby(["source", "dataset", "split", "protocol", "context",
                                                        "rank_group"]):
        assert sorted(group["rank"]) == list(range(1, len(group) + 1))  # ranks restart in every prediction set
    paper = wide[wide["source"] == "paper"]
    assert (paper["rank_group"] == "published").all() and paper["rank"].notna().all()
    tex = latex_table(wide[wide["source"] == "dyadbench"])
    lines = tex.splitlines()
    heads = [line for line in lines if line.startswith(r"\multicolumn") and "ranked among: " in line]
    assert sorted(h.split("ranked among: ")[1].split("}")[0] for h in heads) == sorted([
        unrecorded, "1066 items / 533 clips, data abcdef012345", "1066 items / 533 clips, data 0123456789ab",
        "40 items / 20 clips"])
    bold = [line.split(" &")[0] for line in lines if r"\textbf" in line]
    assert bold == ["full-b", "first-20"]  # best of each set with more than one ranked row
    assert any(line.startswith("% Rows are ranked") for line in lines)


def test_a_suite_without_declaration_is_not_ranked(tmp_path):
    for model, v in (("a", 1.0), ("b", 2.0)):
        _result(tmp_path, "custom", model, {"score": v})
    wide = wide_table(long_table([tmp_path]), "custom")
    assert wide["rank"].isna().all() and list(wide.columns[-1:]) == ["score"]
    assert long_table([tmp_path])["higher_is_better"].isna().all()
