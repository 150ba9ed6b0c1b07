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

from dyadbench.cli import cli, warning_summary
from dyadbench.cli.options import check_cfg_scale
from dyadbench.cli.splits import DATASET_SPLITS
from dyadbench.errors import InputError
from dyadbench.registry import DATASETS, MODELS, SUITES
from tests.cli_run import run


def test_cfg_scale_is_refused_for_models_without_guidance(capsys, tmp_path):
    code, _, err = run(capsys, "eval", "--model", "zero", "--cfg-scale", "3", "--out", tmp_path / "e")
    assert code == 2 and "--cfg-scale 3: zero has no classifier-free guidance" in err and "timar" in err
    assert not (tmp_path / "e").exists()
    code, _, err = run(capsys, "sweep", "--models", "timar,random,zero", "--cfg-scale", "1.5", "--out", tmp_path / "s")
    assert code == 2 and "random, zero have no classifier-free guidance" in err
    check_cfg_scale(["timar", "timar-stream"], 3.0)  # they declare it
    check_cfg_scale(["zero"], 1.0)  # 1 = off: always allowed
    assert [e.name for e in MODELS.entries.values() if "guidance" in e.tags] == ["timar", "timar-stream"]


#: the options each train command requires (the canonical spellings)
REQUIRED = {"sfms-tokenizer": ["--export", "x.pt"], "sfms": ["--export", "x.pt", "--tokenizer", __file__],
            "stygazetalk-style": ["--export", "x.pt"], "stygazetalk": ["--export", "x.pt"]}
#: train command -> its spellings of the weights file and the resumable run folder (None: it has none)
OUTPUTS = {"timar": ("--export", "--run-dir"), "timar-stream": ("--export", "--run-dir"),
           "dualtalk": ("--export", "--run-dir"), "sfms-tokenizer": ("--export", None), "sfms": ("--export", None),
           "stygazetalk-style": ("--export", None), "stygazetalk": ("--export", None)}


def _train_command(name: str) -> click.Command:
    ctx = click.Context(cli)
    return cli.get_command(ctx, "train").get_command(ctx, name)


def _without(args: list[str], option: str) -> list[str]:
    """``args`` (option, value pairs) without ``option`` and its value."""
    pairs = [args[i:i + 2] for i in range(0, len(args), 2)]
    return [x for pair in pairs if pair[0] != option for x in pair]


@pytest.mark.parametrize("name, alias, option, dest, value, parsed", [
    ("sfms-tokenizer", "--root", "--data", "root", "l2l", Path("l2l")),
    ("sfms", "--batch", "--batch-size", "batch", "4", 4),
    ("stygazetalk-style", "--batch", "--batch-size", "batch", "8", 8),
    ("stygazetalk", "--batch", "--batch-size", "batch", "4", 4),
    # --out keeps its old meaning per command: the run folder (timar, timar-stream, dualtalk) ...
    ("timar", "--out", "--run-dir", "run_dir", "runs/r", Path("runs/r")),
    ("timar-stream", "--out", "--run-dir", "run_dir", "runs/r", Path("runs/r")),
    ("dualtalk", "--out", "--run-dir", "run_dir", "runs/r", Path("runs/r")),
    # ... or the checkpoint file (sfms, stygazetalk)
    ("sfms-tokenizer", "--out", "--export", "export", "tok.pt", Path("tok.pt")),
    ("sfms", "--out", "--export", "export", "sfms.pt", Path("sfms.pt")),
    ("stygazetalk-style", "--out", "--export", "export", "se.pt", Path("se.pt")),
    ("stygazetalk", "--out", "--export", "export", "g.pt", Path("g.pt")),
])
def test_older_spellings_are_hidden_and_still_work(name, alias, option, dest, value, parsed, capsys):
    command = _train_command(name)
    base = _without(REQUIRED.get(name, []), option)
    capsys.readouterr()
    assert command.make_context(name, [*base, alias, value]).params[dest] == parsed
    assert capsys.readouterr().err == f"note: {alias} is deprecated, use {option} (same meaning)\n"
    assert command.make_context(name, [*base, option, value]).params[dest] == parsed
    assert capsys.readouterr().err == ""
    if option in REQUIRED.get(name, []):
        with pytest.raises(click.MissingParameter) as missing:
            command.make_context(name, base)
        assert missing.value.format_message() == f"Missing option '{option}'."
    else:
        default = next(p for p in command.params if p.name == dest).default
        assert command.make_context(name, base).params[dest] == default
    help_text = CliRunner().invoke(cli, ["train", name, "--help"]).output
    assert option in help_text and f"{alias} " not in help_text


@pytest.mark.parametrize("name", list(OUTPUTS))
def test_train_help_names_the_weights_file_and_run_folder_alike(name):
    help_text = CliRunner().invoke(cli, ["train", name, "--help"]).output
    export, run_dir = OUTPUTS[name]
    assert re.search(rf"^\s+{export} FILE\s", help_text, re.M), help_text
    assert (re.search(r"^\s+--run-dir DIRECTORY\s", help_text, re.M) is not None) == (run_dir is not None)
    assert "--out " not in help_text


def test_every_train_command_spells_data_root_batch_size_and_outputs_alike():
    ctx = click.Context(cli)
    train = cli.get_command(ctx, "train")
    assert set(train.list_commands(ctx)) == set(OUTPUTS)
    for name in train.list_commands(ctx):
        opts = {o for p in train.get_command(ctx, name).params if not getattr(p, "hidden", False) for o in p.opts}
        assert not opts & {"--root", "--batch", "--out"}, name
        assert {"--data", "--export"} <= opts, name


@pytest.mark.slow  # ~10 s on 2 busy cores; tests/test_sfms_cli.py also trains under --out
def test_old_out_spelling_trains_the_sfms_tokenizer(tmp_path, monkeypatch):
    """A whole (3-step) run under the old spelling writes the checkpoint where ``--out`` said, with the note."""
    from dyadbench.synth.corpus import make_clips
    from models.sfms import cli as sfms_cli

    train, val = make_clips("train", 2, duration_s=6.0), make_clips("val", 1, duration_s=6.0)
    monkeypatch.setattr(sfms_cli, "load_split_clips", lambda *a, **k: (train, val, {"dataset": "generated"}))
    small = ["--set", "width=32", "--set", "heads=2", "--set", "ffn=64", "--set", "pe_dim=8", "--steps", "3",
             "--batch-size", "4", "--val-windows", "8", "--keyframes", "5"]
    res = CliRunner().invoke(cli, ["train", "sfms-tokenizer", *small, "--out", str(tmp_path / "tok.pt")])
    assert res.exit_code == 0, res.output
    assert "note: --out is deprecated, use --export (same meaning)" in res.stderr
    assert (tmp_path / "tok.pt").is_file() and (tmp_path / "tok.history.json").is_file()


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
