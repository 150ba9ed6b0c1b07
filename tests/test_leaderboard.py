"""Leaderboards from result files: long and wide CSV, LaTeX, published rows, oracle never ranked."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from click.testing import CliRunner

from dyadbench.cli import cli
from dyadbench.cli.leaderboard import PAPER_ROWS
from dyadbench.errors import InputError
from dyadbench.leaderboard import TABLE_NAMES, latex_table, long_table, paper_rows, wide_table
from dyadbench.protocol.config import ProtocolConfig
from dyadbench.protocol.interface import ModelOptions
from dyadbench.protocol.runner import evaluate
from dyadbench.registry import DEFAULT_EMBEDDED
from tests.protocol_clips import isolated_cache, make_source  # noqa: F401
from tests.protocol_expectations import corpus_structure_failures

MODELS = ("zero", "mean-frame", "mime", "oracle")


@pytest.fixture(scope="module")
def results_dir(tmp_path_factory):
    root = tmp_path_factory.mktemp("results")
    train = make_source(2, split="train", seed=1, seconds=5.0)
    test = make_source(2, seed=2, seconds=5.0)
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("DYADBENCH_CACHE", str(tmp_path_factory.mktemp("cache")))
        for context in (0, 7):
            for model in MODELS:
                r = evaluate(model, test, ProtocolConfig(context=context),
                             options=ModelOptions(train_split=lambda: train), progress=False)
                r.write(root / "handmade" / "test" / f"n{context}" / f"{model}.json")
    return root


def test_long_table_has_one_row_per_model_setting_and_metric(results_dir):
    long = long_table([results_dir])
    assert set(long["source"]) == {"dyadbench"}
    keys = ["model", "dataset", "split", "protocol", "context", "metric"]
    assert not long.duplicated(keys).any()
    assert len(long) == len(MODELS) * 2 * long["metric"].nunique()
    assert set(long.loc[long["oracle"], "model"]) == {"oracle"}
    row = long[(long["model"] == "mime") & (long["metric"] == "fd_jaw") & (long["context"] == 7)].iloc[0]
    result = json.loads((results_dir / "handmade/test/n7/mime.json").read_text())
    assert row["raw"] == result["metrics"]["fd_jaw"] and row["scaled"] == result["scaled"]["fd_jaw"]
    assert row["scale"] == 1e3 and row["component"] == "jaw" and row["higher_is_better"] == False  # noqa: E712
    assert long.loc[long["metric"] == "sid_exp", "higher_is_better"].eq(True).all()


def test_wide_table_ranks_everyone_but_the_oracle(results_dir):
    wide = wide_table(long_table([results_dir]))
    assert list(wide.columns[:10]) == ["source", "dataset", "split", "protocol", "context", "model", "oracle",
                                       "flags", "rank_group", "rank"]
    assert list(wide.columns[10:14]) == ["items", "fd_exp", "fd_jaw", "fd_pose"] and wide.columns[-1] == "rpcc_pose"
    assert (wide["flags"] == "").all() and wide["rank_group"].nunique() == 1
    assert wide["rank_group"][0] == "4 items / 2 clips"  # one prediction set: one digest, nothing contradicts it
    assert (wide["items"] == 4).all()
    for _, group in wide.groupby("context"):
        ranked = group[~group["oracle"]]
        assert sorted(ranked["rank"].tolist()) == [1, 2, 3]
        assert ranked.sort_values("rank")["fd_exp"].is_monotonic_increasing
        oracle = group[group["oracle"]]
        assert oracle["rank"].isna().all() and oracle.index.max() == group.index.max()  # listed last
        assert np.allclose(oracle[["fd_exp", "pfd_exp", "mse_exp"]].to_numpy(float), 0.0, atol=1e-9)


def test_tables_are_built_only_from_result_files(results_dir, tmp_path):
    copy = tmp_path / "r"
    shutil.copytree(results_dir, copy)
    path = copy / "handmade/test/n0/zero.json"
    data = json.loads(path.read_text())
    data["metrics"]["fd_exp"], data["scaled"]["fd_exp"] = 123.0, 123.0
    path.write_text(json.dumps(data))
    wide = wide_table(long_table([copy]))
    assert wide.loc[(wide["model"] == "zero") & (wide["context"] == "0"), "fd_exp"].item() == 123.0


def test_duplicate_runs_are_rejected(results_dir, tmp_path):
    copy = tmp_path / "r"
    shutil.copytree(results_dir, copy)
    shutil.copy(copy / "handmade/test/n0/zero.json", copy / "zero-again.json")
    with pytest.raises(InputError, match="several result files"):
        long_table([copy])


def test_runs_differing_only_in_speech_normalisation_are_separate_rows(results_dir, tmp_path):
    copy = tmp_path / "r"
    shutil.copytree(results_dir, copy)
    data = json.loads((copy / "handmade/test/n0/zero.json").read_text())
    data["protocol"]["speech_norm"] = "clip"
    (copy / "handmade/test/n0/zero@speech-clip.json").write_text(json.dumps(data))
    wide = wide_table(long_table([copy]))
    at_zero = wide[wide["context"] == "0"]
    assert {"zero", "zero (speech-clip)"} <= set(at_zero["model"])


def test_embedded_corpora_are_labelled_with_their_version_and_the_default_comes_first(results_dir, tmp_path):
    copy = tmp_path / "r"
    for dataset in ("synthetic", "synthetic-v2"):
        for path in (results_dir / "handmade").rglob("*.json"):
            data = json.loads(path.read_text())
            data["data"]["dataset"] = dataset
            target = copy / dataset / path.relative_to(results_dir / "handmade")
            target.parent.mkdir(parents=True, exist_ok=True)
            target.write_text(json.dumps(data))
    wide = wide_table(long_table([copy]))
    other = ({"synthetic", "synthetic-v2"} - {DEFAULT_EMBEDDED}).pop()
    datasets = list(dict.fromkeys(wide["dataset"]))
    assert datasets == [DEFAULT_EMBEDDED, other]
    tex = latex_table(wide)
    version = {"synthetic": "1", "synthetic-v2": "2"}
    assert rf"\emph{{{DEFAULT_EMBEDDED} (v{version[DEFAULT_EMBEDDED]}, default) test, streaming" in tex
    assert rf"\emph{{{other} (v{version[other]}) test, streaming" in tex
    assert tex.index(f"{DEFAULT_EMBEDDED} (v") < tex.index(f"{other} (v")


def test_published_rows_are_the_timar_tables():
    rows = paper_rows(PAPER_ROWS)
    assert set(rows["source"]) == {"paper"} and not rows["oracle"].any()
    assert len(rows) == 34 * 15  # Table 1: 2 splits x 3 contexts x 3 models; Table 2: 2 splits x 8 models
    timar = rows[(rows["model"] == "TIMAR") & (rows["split"] == "test") & (rows["context"] == 7)]
    printed = dict(zip(timar["metric"], timar["scaled"]))
    raw = dict(zip(timar["metric"], timar["raw"]))
    # The reference values of metrics-dualtalk.md (TIMAR test set, n = 7).
    assert printed["fd_exp"] == 8.97 and printed["fd_jaw"] == 1.57 and printed["fd_pose"] == 3.08
    assert printed["pfd_exp"] == 9.93 and printed["mse_exp"] == 3.58 and printed["sid_exp"] == 3.53
    assert printed["rpcc_exp"] == 4.12
    assert raw["mse_exp"] == pytest.approx(0.358) and raw["fd_jaw"] == pytest.approx(1.57e-3)
    assert raw["rpcc_exp"] == pytest.approx(0.0412)
    table2 = rows[rows["protocol"] == "offline"]
    assert table2["context"].isna().all()
    assert sorted(table2["model"].unique()) == sorted(
        ["FaceFormer", "CodeTalker", "EmoTalk", "SelfTalk", "L2L", "DualTalk-official", "DualTalk-retrained",
         "TIMAR"])
    codetalker = table2[(table2["model"] == "CodeTalker") & (table2["split"] == "ood")]
    assert dict(zip(codetalker["metric"], codetalker["scaled"]))["fd_pose"] == 11.66


def test_bad_published_rows_are_named(tmp_path):
    bad = tmp_path / "bad.csv"
    pd.read_csv(PAPER_ROWS).rename(columns={"fd_exp": "fid_exp"}).to_csv(bad, index=False)
    with pytest.raises(InputError, match="unknown dualtalk metric columns: fid_exp"):
        paper_rows(bad)


def test_latex_marks_oracle_and_best(results_dir):
    wide = wide_table(long_table([results_dir]))
    tex = latex_table(wide)
    assert tex.startswith(r"\begin{tabular}") and r"\end{tabular}" in tex
    assert r"oracle$^\dagger$" in tex and r"\textbf{" in tex and r"FD jaw$\downarrow$ $\times10^{3}$" in tex
    oracle_line = next(line for line in tex.splitlines() if line.startswith("oracle"))
    assert r"\textbf" not in oracle_line


def test_leaderboard_command_writes_atomically_and_deterministically(results_dir, tmp_path):
    out = tmp_path / "lb"
    args = ["leaderboard", str(results_dir), "--out", str(out), "--latex"]
    result = CliRunner().invoke(cli, args, catch_exceptions=False)
    assert result.exit_code == 0, result.output
    assert sorted(p.name for p in out.iterdir()) == ["dualtalk_wide.csv", "dualtalk_wide.tex", "long.csv"]
    first = {p.name: p.read_bytes() for p in out.iterdir()}
    CliRunner().invoke(cli, args, catch_exceptions=False)
    assert {p.name: p.read_bytes() for p in out.iterdir()} == first
    long = pd.read_csv(out / "long.csv")
    assert set(long["source"]) == {"dyadbench", "paper"}
    result = CliRunner().invoke(cli, args + ["--no-paper"], catch_exceptions=False)
    assert set(pd.read_csv(out / "long.csv")["source"]) == {"dyadbench"}


# --- the committed leaderboards of the embedded benchmark ------------------------------------------

REPO = Path(__file__).resolve().parents[1]
BASELINES = ("zero", "mean-frame", "median-frame", "random", "mime", "lagged-mirror", "nn-retrieval", "oracle")


def _committed_long() -> pd.DataFrame:
    return pd.read_csv(REPO / "leaderboards" / "long.csv", dtype={"context": "Int64"})


def test_committed_leaderboards_are_rebuilt_exactly_from_committed_results(tmp_path, monkeypatch):
    monkeypatch.chdir(REPO)
    result = CliRunner().invoke(cli, ["leaderboard", "results", "--out", str(tmp_path), "--latex"],
                                catch_exceptions=False)
    assert result.exit_code == 0, result.output
    committed = {p.name for pattern in TABLE_NAMES for p in (REPO / "leaderboards").glob(pattern)}
    assert {"long.csv", "dualtalk_wide.tex", "gaze_wide.csv", "gaze_wide.tex", "l2l_wide.csv"} <= committed
    assert {p.name for p in tmp_path.iterdir()} == committed  # the build writes every committed table, no other
    for name in sorted(committed):
        assert (tmp_path / name).read_bytes() == (REPO / "leaderboards" / name).read_bytes(), name


@pytest.mark.parametrize("dataset", ["synthetic", "synthetic-v2"])
def test_committed_leaderboard_has_every_baseline_at_n_0_3_7_on_test_and_ood(dataset):
    long = _committed_long()
    ours = long[(long["source"] == "dyadbench") & (long["dataset"] == dataset)]
    for split in ("test", "ood"):
        for n in (0, 3, 7):
            models = set(ours.loc[(ours["split"] == split) & (ours["context"] == n), "model"])
            assert set(BASELINES) <= models, (split, n, sorted(set(BASELINES) - models))


def test_committed_leaderboard_shows_the_corpus_structure_on_test_at_n_7():
    long = _committed_long()
    part = long[(long["source"] == "dyadbench") & (long["dataset"] == "synthetic") & (long["split"] == "test")
                & (long["context"] == 7)]
    scores = {model: dict(zip(g["metric"], g["raw"])) for model, g in part.groupby("model")}
    assert corpus_structure_failures(scores) == []
