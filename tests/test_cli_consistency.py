"""One spelling per concept across commands (older spellings hidden but working), options checked against the
model, help that lists what a command accepts, warnings summarised and errors on their own line."""

import importlib
import re
import warnings
from pathlib import Path

import click
import numpy as np
import pytest
from click.testing import CliRunner
from tqdm import tqdm

from dyadbench.cli import cli, main, warning_summary
from dyadbench.cli.options import check_cfg_scale
from dyadbench.cli.splits import DATASET_SPLITS
from dyadbench.errors import InputError
from dyadbench.registry import DATASETS, MODELS, SUITES


def run(capsys, *args):
    try:
        main([*map(str, args)])
        code = 0
    except SystemExit as exc:
        code = exc.code
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def test_cfg_scale_is_refused_for_models_without_guidance(capsys, tmp_path):
    code, _, err = run(capsys, "eval", "--model", "zero", "--cfg-scale", "3", "--out", tmp_path / "e")
    assert code == 2 and "--cfg-scale 3: zero has no classifier-free guidance" in err and "timar" in err
    assert not (tmp_path / "e").exists()
    code, _, err = run(capsys, "sweep", "--models", "timar,random,zero", "--cfg-scale", "1.5", "--out", tmp_path / "s")
    assert code == 2 and "random, zero have no classifier-free guidance" in err
    check_cfg_scale(["timar", "timar-stream"], 3.0)  # they declare it
    check_cfg_scale(["zero"], 1.0)  # 1 = off: always allowed
    assert [e.name for e in MODELS.entries.values() if "guidance" in e.tags] == ["timar", "timar-stream"]


@pytest.mark.parametrize("command, alias, option, dest, value, parsed", [
    (("train", "sfms-tokenizer"), "--root", "--data", "root", "l2l", Path("l2l")),
    (("train", "sfms"), "--batch", "--batch-size", "batch", "4", 4),
    (("train", "stygazetalk-style"), "--batch", "--batch-size", "batch", "8", 8),
    (("train", "stygazetalk"), "--batch", "--batch-size", "batch", "4", 4),
])
def test_older_spellings_are_hidden_and_still_work(command, alias, option, dest, value, parsed):
    group = cli
    ctx = click.Context(cli)
    for name in command:
        group = group.get_command(ctx, name)
    base = ["--out", "x.pt"] + (["--tokenizer", __file__] if command[-1] == "sfms" else [])
    assert group.make_context(group.name, [*base, alias, value]).params[dest] == parsed
    assert group.make_context(group.name, [*base, option, value]).params[dest] == parsed
    assert group.make_context(group.name, base).params[dest] is None
    help_text = CliRunner().invoke(cli, [*command, "--help"]).output
    assert option in help_text and f"{alias} " not in help_text


def test_every_train_command_spells_data_root_and_batch_size_alike():
    ctx = click.Context(cli)
    train = cli.get_command(ctx, "train")
    for name in train.list_commands(ctx):
        opts = {o for p in train.get_command(ctx, name).params if not getattr(p, "hidden", False) for o in p.opts}
        assert "--root" not in opts and "--batch" not in opts, name
        assert "--data" in opts, name


def test_split_help_lists_every_dataset_and_matches_the_adapters():
    assert set(DATASET_SPLITS) == set(DATASETS.names())
    declared = {"dualtalk": "dyadbench.datasets.dualtalk", "l2l": "dyadbench.datasets.l2l",
                "react": "dyadbench.datasets.react", "synthetic-gaze": "dyadbench.synth.gaze"}
    for name, module in declared.items():
        assert DATASET_SPLITS[name] == ", ".join(importlib.import_module(module).SPLITS), name
    from dyadbench.synth.styles import SPLIT_POOL

    assert set(DATASET_SPLITS["synthetic"].split(", ")) == set(SPLIT_POOL)
    seamless = pytest.importorskip("dyadbench.datasets.seamless_files")
    assert DATASET_SPLITS["seamless"] == ", ".join(seamless.SPLITS)
    text = " ".join(CliRunner().invoke(cli, ["eval", "--help"]).output.split())
    assert "react: train, val, test" in text and "seamless: train, dev, test" in text


def test_score_help_documents_the_prediction_format_of_every_suite():
    text = CliRunner().invoke(cli, ["score", "--help"]).output
    for suite in SUITES.names():
        assert re.search(rf"^ +{suite} +\S", text, re.M), suite
    for form in ("_speaker1.npy", "(10, T, 25)", "_listener.npy", "_subject.npy", "(T, 7)", ".npz"):
        assert form in text


def test_warnings_are_summarised_one_line_per_kind(capsys, tmp_path):
    """Constant predictions make scipy's sqrtm warn once per Fréchet distance: one line with the count."""
    from dyadbench.datasets.dualtalk_files import write_gt_npz

    gt, pred = tmp_path / "gt", tmp_path / "pred"
    gt.mkdir()
    pred.mkdir()
    rng = np.random.default_rng(0)
    for k in (1, 2):
        write_gt_npz(gt / f"c_speaker{k}.npz", np.cumsum(rng.normal(size=(60, 56)) * 0.05, axis=0))
        np.save(pred / f"c_speaker{k}.npy", np.zeros((60, 56), np.float32))
    code, _, err = run(capsys, "score", pred, "--gt", gt)
    assert code == 0
    lines = [line for line in err.splitlines() if "LinAlgWarning" in line]
    assert len(lines) == 1 and lines[0].startswith("warning: LinAlgWarning x") and "frechet.py" in lines[0]
    assert int(lines[0].split(" x", 1)[1].split(":")[0]) >= 6  # FD and P-FD of 3 components, 2 clips


def test_warning_summary_counts_each_kind():
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        for _ in range(3):
            warnings.warn("a", RuntimeWarning)
        warnings.warn("b", UserWarning)
    assert [line.split(" (first")[0] for line in warning_summary(caught)] == [
        "warning: RuntimeWarning x3: a", "warning: UserWarning x1: b"]


def test_an_error_is_printed_on_its_own_line_after_a_progress_bar(capsys, monkeypatch, tmp_path):
    def failing(pred, gt, **kwargs):
        bar = tqdm(total=2, desc="dualtalk", disable=False, leave=False)
        bar.update(1)
        raise InputError(gt, "broken on purpose")

    monkeypatch.setattr(SUITES, "load", lambda name: failing)
    code, _, err = run(capsys, "score", tmp_path, "--gt", tmp_path)
    assert code == 2 and "dualtalk" in err  # the bar was drawn
    last = err.rstrip("\n").replace("\r", "\n").splitlines()[-1]
    assert last == f"error: {tmp_path}: broken on purpose"
