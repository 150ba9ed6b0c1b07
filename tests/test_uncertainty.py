"""Standard errors and cluster-bootstrap CIs (dyadbench.uncertainty), and `dyadbench compare`.

Expected values are derived by hand in the comments or computed independently with numpy.
"""

from __future__ import annotations

import io
import itertools
import json
import math

import numpy as np
import pandas as pd
import pytest

from dyadbench import atomic
from dyadbench.compare import Run, compare
from dyadbench.metrics import l2l as l2l_suite
from dyadbench.results import EvalResult
from dyadbench.scoring import l2l as l2l_scoring
from dyadbench.scoring.dualtalk import score_arrays
from dyadbench.scoring.gaze import pooled_statistics
from dyadbench.scoring.report import ScoreItem
from dyadbench.uncertainty import Bootstrap, dialogue_of, estimate
from tests.hostile_cli import dyadbench, error_line


def _singletons(n: int) -> list[str]:
    return [f"c{i:04d}" for i in range(n)]


def test_standard_error_of_iid_values_is_sigma_over_root_n():
    sigma, n = 2.0, 400
    values = np.random.default_rng(1).normal(5.0, sigma, n)
    spread = Bootstrap.of(_singletons(n), seed=0).mean(values)
    # one item per dialogue: the cluster-robust s.e. is the textbook s / sqrt(n) (ddof = 1) ...
    assert spread["se"] == pytest.approx(np.std(values, ddof=1) / math.sqrt(n), rel=1e-12)
    # ... which estimates sigma / sqrt(n) = 0.1
    assert spread["se"] == pytest.approx(sigma / math.sqrt(n), rel=0.1)


def test_bootstrap_ci_covers_the_true_mean_about_95_percent_of_the_time():
    repetitions, n, covered = 200, 40, 0
    for rep in range(repetitions):
        values = np.random.default_rng([7, rep]).normal(3.0, 1.5, n)
        spread = Bootstrap.of(_singletons(n), seed=rep).mean(values)
        covered += spread["ci_low"] <= 3.0 <= spread["ci_high"]
    # binomial(200, 0.95): mean 190, s.d. 3.1; the percentile interval runs slightly narrow at n = 40
    assert 176 <= covered <= 199


def test_two_dialogues_enumerated_by_hand():
    # dialogue d1 holds items 1 and 3, d2 item 10. Drawing 2 dialogues with replacement gives d1d1 (mean 2),
    # d2d2 (mean 10) or a mixed draw (mean 14/3), d1d1 and d2d2 each with probability 1/4 >> 2.5 %, so the
    # 95 % percentile CI is [2, 10]. s.e.: C = 2, N = 3, m = 14/3, S = (4, 10), n = (2, 1):
    # residuals S - n m = (-16/3, 16/3), se^2 = 2/1 * (512/9) / 9 = 1024/81, se = 32/9.
    plan = Bootstrap.of(["d1", "d1", "d2"], seed=3)
    spread = plan.mean(np.array([1.0, 3.0, 10.0]))
    assert spread["ci_low"] == 2.0 and spread["ci_high"] == 10.0
    assert spread["se"] == pytest.approx(32 / 9, rel=1e-12)


def test_three_dialogues_bootstrap_distribution_matches_the_enumeration():
    dialogues, values = ["a", "a", "b", "c", "c", "c"], np.array([1.0, 2.0, 4.0, 0.0, 6.0, 9.0])
    members = {d: values[[i for i, x in enumerate(dialogues) if x == d]] for d in "abc"}
    # all 27 equally likely ordered draws of 3 dialogues with replacement, each replicate the pooled mean
    exact = np.array([np.concatenate([members[d] for d in draw]).mean() for draw in itertools.product("abc", repeat=3)])
    plan = Bootstrap.of(dialogues, seed=0, resamples=20000)
    replicates = (plan.item_weights @ values) / plan.item_weights.sum(axis=1)
    assert replicates.mean() == pytest.approx(exact.mean(), abs=0.03)
    assert replicates.std() == pytest.approx(exact.std(), rel=0.03)
    spread = plan.statistic(lambda w: (w @ values) / w.sum(axis=1))
    assert spread["se"] == pytest.approx(exact.std(), rel=0.03)


def test_both_directions_of_a_dialogue_are_resampled_together():
    # C dialogues whose two directions score the same value y_c. Clustered: se^2 = s_c^2 / C (s_c over the
    # C dialogue values, ddof 1). Treated as 2C independent items: se^2 = sum (y_c - m)^2 / ((2C - 1) C).
    # Their ratio of squares is (2C - 1) / (C - 1).
    C = 30
    y = np.random.default_rng(2).normal(0.0, 1.0, C)
    rows = [{"clip": f"dlg{c:02d}_speaker{k}", "x": y[c]} for c in range(C) for k in (1, 2)]
    apart = [{"clip": f"dlg{c:02d}k{k}_speaker1", "x": y[c]} for c in range(C) for k in (1, 2)]
    clustered, method = estimate("dualtalk", rows, ["x"], seed=0)
    naive, _ = estimate("dualtalk", apart, ["x"], seed=0)
    assert method["clusters"] == C
    assert clustered["x"]["se"] == pytest.approx(np.std(y, ddof=1) / math.sqrt(C), rel=1e-12)
    assert (clustered["x"]["se"] / naive["x"]["se"]) ** 2 == pytest.approx((2 * C - 1) / (C - 1), rel=1e-12)
    assert clustered["x"]["ci_high"] - clustered["x"]["ci_low"] > naive["x"]["ci_high"] - naive["x"]["ci_low"]


def test_dialogue_of_each_suite():
    assert dialogue_of("dualtalk", "synth_test_00001_speaker2") == "synth_test_00001"
    assert dialogue_of("react", "NoXI/065_2016/Expert_video/3") == "NoXI/065_2016"
    assert dialogue_of("react", "NoXI/065_2016/Novice_video/1") == "NoXI/065_2016"
    assert dialogue_of("gaze", "s07-f1200_subject") == dialogue_of("gaze", "s07") == "s07"
    assert dialogue_of("l2l", "conan_test_00003_listener") == "conan_test_00003"


def test_same_seed_gives_byte_identical_records():
    rows = [{"clip": f"d{i // 2}_speaker{i % 2 + 1}", "x": float(i) ** 1.5, "y": math.sin(i)} for i in range(20)]
    first, second, other = (estimate("dualtalk", rows, ["x", "y"], seed=s) for s in (5, 5, 6))
    assert atomic.to_json(first) == atomic.to_json(second)
    assert atomic.to_json(first) != atomic.to_json(other)
    assert first[1] == {**first[1], "method": "cluster bootstrap over dialogues", "resamples": 1000,
                        "level": 0.95, "seed": 5, "clusters": 10}


def _item(stem: str, rng: np.random.Generator) -> ScoreItem:
    gt, partner = rng.normal(size=(60, 56)), rng.normal(size=(60, 56))
    return ScoreItem(stem, gt + rng.normal(scale=0.3, size=gt.shape), gt, partner)


def test_every_dualtalk_column_gets_an_uncertainty_that_survives_dropping_per_clip(tmp_path):
    rng = np.random.default_rng(0)
    report = score_arrays([_item(f"c{i}_speaker{k}", rng) for i in range(3) for k in (1, 2)], seed=4)
    assert set(report.uncertainty) == set(report.metrics)
    assert report.uncertainty_method["clusters"] == 3 and report.uncertainty_method["seed"] == 4
    mse = np.array([row["mse_jaw"] for row in report.per_item])
    sums = mse.reshape(3, 2).sum(axis=1)
    expected = math.sqrt(3 / 2 * np.sum((sums - 2 * mse.mean()) ** 2)) / 6
    assert report.uncertainty["mse_jaw"]["se"] == pytest.approx(expected, rel=1e-12)
    written = json.loads(atomic.to_json(report.to_dict()))
    assert written["uncertainty"]["mse_jaw"]["se"] == pytest.approx(expected, rel=1e-12)


def _result_dict(model: str, **extra) -> dict:
    return {"schema": "dyadbench.eval-result/1", "suite": "dualtalk", "metrics": {"mse_jaw": 0.002},
            "scaled": {"mse_jaw": 2.0}, "scaling": {"mse_jaw": 1000.0}, "per_clip": {"columns": [], "rows": []},
            "model": {"name": model, "version": "1", "weights_digest": None, "weights_path": None, "oracle": False,
                      "layout": "flame56", "config": {}},
            "data": {"dataset": "d", "split": "test", "root": None, "clips": 1, "items": 2},
            "protocol": {"name": "streaming", "turn_seconds": 1.0, "context": 0, "tail": "t", "history_agent": "h",
                         "cfg_scale": 1.0, "seed": 0},
            "timing": {"wall_s": 1.0, "model_s": 1.0, "turns": 1, "mean_turn_latency_s": 1.0}, **extra}


def test_old_result_files_load_without_uncertainty():
    result = EvalResult.from_dict(_result_dict("m"))
    assert result.uncertainty == {} and result.uncertainty_method == {}


def test_leaderboard_uncertainty_columns_are_scaled_like_the_values(tmp_path):
    from dyadbench.leaderboard import long_table, table_texts  # noqa: PLC0415

    (tmp_path / "new.json").write_text(json.dumps(_result_dict(
        "new", uncertainty={"mse_jaw": {"se": 0.0005, "ci_low": 0.001, "ci_high": 0.003}})))
    (tmp_path / "old.json").write_text(json.dumps(_result_dict("old", protocol={
        "name": "streaming", "turn_seconds": 1.0, "context": 0, "tail": "t", "history_agent": "h", "cfg_scale": 1.0,
        "seed": 1})))
    long = long_table([tmp_path])
    plain = table_texts(long)["dualtalk_wide.csv"]
    assert "mse_jaw_se" not in plain
    for mode, expected in (("se", {"mse_jaw_se": 0.5}), ("ci", {"mse_jaw_ci_low": 1.0, "mse_jaw_ci_high": 3.0})):
        tables = table_texts(long, latex=True, uncertainty=mode)
        wide = pd.read_csv(io.StringIO(tables["dualtalk_wide.csv"]))
        wide.index = wide["model"].str.split(" ").str[0]  # labels carry the run's non-default settings
        columns = list(wide.columns)
        assert columns[columns.index("mse_jaw") + 1: columns.index("mse_jaw") + 1 + len(expected)] == list(expected)
        for column, value in expected.items():  # recorded raw x the column's scale (1e3)
            assert wide.loc["new", column] == pytest.approx(value)
            assert pd.isna(wide.loc["old", column])
    assert r"\textbf{2.00} [1.00, 3.00]" in tables["dualtalk_wide.tex"]  # both rows are 2.00: both bold
    assert r"\textbf{2.00} $\pm$ 0.50" in table_texts(long, latex=True, uncertainty="se")["dualtalk_wide.tex"]


def test_gaze_pooled_columns_are_recomputed_from_frame_counts():
    counts = [{"pred_fix": 3, "pred_sac": 1, "gt_fix": 1, "gt_sac": 1, "pred_comp_sum": 2.0, "pred_comp_n": 4,
               "gt_comp_sum": 1.0, "gt_comp_n": 2},
              {"pred_fix": 1, "pred_sac": 3, "gt_fix": 2, "gt_sac": 0, "pred_comp_sum": 6.0, "pred_comp_n": 4,
               "gt_comp_sum": 3.0, "gt_comp_n": 2}]
    stats = pooled_statistics(counts)
    w = np.array([[1.0, 1.0], [2.0, 0.0]])  # the split itself; sequence 0 drawn twice
    # pooled: fix 4/8, gt 3/4, comp 8/8, gt 4/4 -> sim 1 - (0.25 + 0); twice seq 0: fix 6/8, gt 2/4, comp 4/8, gt 2/4
    assert stats["fix_ratio"](w).tolist() == [0.5, 0.75]
    assert stats["saccade_ratio"](w).tolist() == [0.5, 0.25]
    assert stats["comp_score"](w).tolist() == [1.0, 0.5]
    assert stats["sim_gt"](w).tolist() == [0.75, 0.75]


def test_l2l_pooled_statistics_with_unit_weights_equal_the_suite():
    rng = np.random.default_rng(3)
    lengths = (30, 45, 38)
    gts = [rng.normal(size=(t, 56)) for t in lengths]
    preds = [g + rng.normal(scale=0.5, size=g.shape) for g in gts]
    speakers = [rng.normal(size=(t + 2, 56)) + 0.3 * np.pad(g, ((0, 2), (0, 0))) for t, g in zip(lengths, gts)]
    params = l2l_suite.L2LParams()
    metrics, _ = l2l_suite.split_metrics(preds, gts, speakers, params)
    stats = l2l_scoring.pooled_statistics(preds, gts, speakers, params)
    for key, fn in stats.items():
        assert fn(np.ones((1, 3)))[0] == pytest.approx(metrics[key], rel=1e-9), key


def _run(name: str, values: dict[str, list[float]]) -> Run:
    n = len(next(iter(values.values())))
    rows = [{"clip": f"d{i // 2}_speaker{i % 2 + 1}", **{k: v[i] for k, v in values.items()}} for i in range(n)]
    return Run(source=name, suite="dualtalk", metrics=tuple(values), rows=rows)


def test_compare_two_runs_differing_by_a_constant():
    base = [0.125 * k for k in (3, 9, 1, 4, 7, 2, 8, 5)]
    a = _run("a.json", {"mse_jaw": base, "sid_exp": base})
    b = _run("b.json", {"mse_jaw": [x + 0.5 for x in base], "sid_exp": [x + 0.25 for x in base]})
    comparison = compare(a, b, seed=1)
    assert comparison["notes"] and "fewer than 20 dialogues" in comparison["notes"][0]  # 4 dialogues here
    columns = {c["metric"]: c for c in comparison["columns"]}
    mse, sid = columns["mse_jaw"], columns["sid_exp"]
    assert (mse["diff"], mse["se"], mse["ci_low"], mse["ci_high"]) == (0.5, 0.0, 0.5, 0.5)
    assert mse["significant"] and mse["better"] == "A" and mse["p_value"] == 0.0  # lower MSE is better: A
    assert (sid["diff"], sid["se"]) == (0.25, 0.0) and sid["better"] == "B"  # higher SID is better: B
    same = {c["metric"]: c for c in compare(a, a)["columns"]}["mse_jaw"]
    assert not same["significant"] and same["better"] == "="


def _score_output(folder, clips: list[str], mse: list[float]):
    folder.mkdir()
    (folder / "results.json").write_text(json.dumps({  # as written by `score` before it wrote result.json
        "suite": "dualtalk", "metrics": {"mse_jaw": 0.0}, "n_scored": len(clips),
        "config": {"suite": "dualtalk", "pred": "preds", "gt": "gt/test", "seed": 0},
        "coverage": {"expected": len(clips), "scored": len(clips), "missing": [], "extra": []}}))
    pd.DataFrame({"clip": clips, "mse_jaw": mse}).to_csv(folder / "per_clip.csv", index=False)
    return folder


def test_compare_command_writes_json_and_csv_and_refuses_other_items(tmp_path, capsys):
    clips = [f"d{i}_speaker{k}" for i in range(3) for k in (1, 2)]
    a = _score_output(tmp_path / "a", clips, [1.0, 2.0, 3.0, 4.0, 5.0, 6.0])
    b = _score_output(tmp_path / "b", clips, [0.0, 1.0, 2.0, 3.0, 4.0, 5.0])
    code, out = dyadbench(capsys, "compare", a, b, "--out", tmp_path / "cmp")
    assert code == 0, out
    written = json.loads((tmp_path / "cmp" / "compare.json").read_text())
    assert written["columns"][0]["diff"] == -1.0 and written["columns"][0]["better"] == "B"
    assert pd.read_csv(tmp_path / "cmp" / "compare.csv")["metric"].tolist() == ["mse_jaw"]
    c = _score_output(tmp_path / "c", clips[:4], [1.0, 2.0, 3.0, 4.0])
    code, out = dyadbench(capsys, "compare", a, c)
    assert code == 2 and str(a / "results.json") in error_line(out) and str(c / "results.json") in error_line(out)
    (c / "per_clip.csv").unlink()
    code, out = dyadbench(capsys, "compare", a, c)
    assert code == 2 and "per_clip.csv" in error_line(out)


def test_react_columns_are_resampled_by_session_and_frdvs_is_marked_unavailable():
    from dyadbench.scoring.react import score_arrays as score_react  # noqa: PLC0415

    rng = np.random.default_rng(5)
    items = [ScoreItem(f"Synth/c{i // 2}/speaker{i % 2 + 1}/1", rng.random((2, 20, 25)), rng.random((20, 25)),
                       rng.random((20, 25))) for i in range(6)]
    report = score_react(items)
    assert report.uncertainty_method["clusters"] == 3
    assert set(report.uncertainty["FRDvs"]) == {"unavailable"}
    frcorr = np.array([row["FRCorr"] for row in report.per_item])
    sums = frcorr.reshape(3, 2).sum(axis=1)
    assert report.uncertainty["FRCorr"]["se"] == pytest.approx(
        math.sqrt(3 / 2 * np.sum((sums - 2 * frcorr.mean()) ** 2)) / 6, rel=1e-12)
    syn = report.uncertainty["FRSyn_all"]
    assert syn["ci_low"] <= report.metrics["FRSyn_all"] <= syn["ci_high"]
