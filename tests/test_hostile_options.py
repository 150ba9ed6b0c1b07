"""Hostile option values: every numeric option of every command has a domain, and values outside it
(negative, zero where a count or positive number is needed, NaN, inf) are usage errors (exit 2, one
message naming the option, no traceback) before any work, so no checkpoint or output is ever written.
``--set FIELD=VALUE`` config overrides are checked against each field's declared domain."""

from __future__ import annotations

import importlib

import click
import pytest

from dyadbench.cli import cli, main
from dyadbench.cli.options import FiniteFloatRange, IntList
from dyadbench.synth.writers import write_dualtalk_split
from tests.protocol_clips import isolated_cache  # noqa: F401

#: Commands that are not sub-commands of ``dyadbench`` but have options of their own.
SCRIPTS = {"python -m models.sfms.l2l_compare": "models.sfms.l2l_compare:main"}
#: Numeric options for which 0 is a meaningful value (a seed, no history, no warm-up, a weight of 0).
ZERO_ALLOWED = {"--seed", "--context", "--contexts", "--cfg-scale", "--warmup-epochs", "--lam", "--rollout-prob"}


def _commands(group: click.Group = cli, path: tuple[str, ...] = ()) -> list[tuple[tuple[str, ...], click.Command]]:
    """Every leaf command of ``dyadbench`` with its argument path, e.g. (("train", "sfms"), <command>)."""
    ctx = click.Context(group)
    out = []
    for name in group.list_commands(ctx):
        command = group.get_command(ctx, name)
        if isinstance(command, click.Group):
            out += _commands(command, path + (name,))
        else:
            out.append((path + (name,), command))
    return out


def _numeric_options() -> list[tuple[tuple[str, ...], click.Command, click.Option]]:
    commands = _commands()
    for label, target in SCRIPTS.items():
        module, _, attr = target.partition(":")
        commands.append(((label,), getattr(importlib.import_module(module), attr)))
    numeric = (click.types.IntParamType, click.types.FloatParamType, IntList)
    return [(path, command, p) for path, command in commands for p in command.params
            if isinstance(p, click.Option) and isinstance(p.type, numeric)]


NUMERIC = _numeric_options()


def test_every_numeric_option_has_a_bounded_finite_type():
    assert len(NUMERIC) >= 40  # the walk found the commands (eval, sweep, score, data, train ..., l2l_compare)
    unbounded = [f"{' '.join(path)} {p.opts[0]}" for path, _, p in NUMERIC
                 if not isinstance(p.type, IntList) and getattr(p.type, "min", None) is None]
    infinite = [f"{' '.join(path)} {p.opts[0]}" for path, _, p in NUMERIC
                if isinstance(p.type, click.types.FloatParamType) and not isinstance(p.type, FiniteFloatRange)]
    assert unbounded == [] and infinite == []


def _cases():
    for path, command, option in NUMERIC:
        values = ["-1", "nan"] + ([] if option.opts[0] in ZERO_ALLOWED else ["0"])
        if isinstance(option.type, click.types.FloatParamType):
            values.append("inf")
        for value in values:
            yield pytest.param(path, command, option.opts[0], value, id=f"{'-'.join(path)}{option.opts[0]}={value}")


@pytest.mark.parametrize("path,command,option,value", list(_cases()))
def test_out_of_range_values_are_usage_errors_before_any_work(path, command, option, value, tmp_path,
                                                              monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)  # a default output folder (e.g. runs/) would appear here
    out = tmp_path / "written.pt"
    output = [o for p in command.params if not getattr(p, "hidden", False)
              for o in p.opts if o in ("--out", "--export")]
    args = [option, value] + ([output[0], str(out)] if output else [])
    with pytest.raises(SystemExit) as exc:
        if path[0] in SCRIPTS:
            command.main(args=args, prog_name=path[0], standalone_mode=True)
        else:
            main([*path, *args])
    err = capsys.readouterr().err
    assert exc.value.code == 2, err
    assert f"Invalid value for '{option}'" in err and "Traceback" not in err
    assert list(tmp_path.iterdir()) == []


def test_sfms_tokenizer_negative_steps_writes_no_checkpoint(tmp_path, capsys):
    out = tmp_path / "tok.pt"
    with pytest.raises(SystemExit) as exc:
        main(["train", "sfms-tokenizer", "--steps", "-1", "--export", str(out)])
    err = capsys.readouterr().err
    assert exc.value.code == 2 and "'--steps': -1 is not in the range x>=1" in err
    assert not out.exists() and not out.with_suffix(".history.json").exists()


@pytest.mark.parametrize("command,override,message", [
    ("sfms-tokenizer", "steps=-1", "TokenizerConfig.steps = -1 must be a finite number > 0"),
    ("sfms-tokenizer", "batch=0", "TokenizerConfig.batch = 0 must be a finite number > 0"),
    ("sfms-tokenizer", "dropout=NaN", "TokenizerConfig.dropout = nan must be a finite number in [0, 1]"),
    ("sfms-tokenizer", "dropout=1.5", "TokenizerConfig.dropout = 1.5 must be a finite number in [0, 1]"),
    ("sfms-tokenizer", "betas=[0.9,1.0]", "TokenizerConfig.betas = (0.9, 1.0) must be a finite number in [0, 1)"),
    ("sfms-tokenizer", "suppression_radius=-2", "TokenizerConfig.suppression_radius = -2 must be"),
    ("sfms", "lr=-0.001", "PredictorConfig.lr = -0.001 must be a finite number > 0"),
    ("sfms", "temperature=Infinity", "PredictorConfig.temperature = inf must be a finite number > 0"),
    ("sfms", "neutral_prob=2", "PredictorConfig.neutral_prob = 2 must be a finite number in [0, 1]"),
    ("sfms", "keyframe_cap=0", "PredictorConfig.keyframe_cap = 0 must be a finite number > 0"),
])
def test_config_overrides_outside_their_domain_are_refused(command, override, message, tmp_path, capsys):
    out = tmp_path / "model.pt"
    extra = ["--tokenizer", str(_dummy(tmp_path))] if command == "sfms" else []
    with pytest.raises(SystemExit) as exc:
        main(["train", command, "--set", override, "--export", str(out), *extra])
    err = capsys.readouterr().err
    assert exc.value.code == 2 and err.startswith(f"error: {message}")
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err
    assert not out.exists()


def _dummy(folder):
    path = folder / "tokenizer.pt"
    path.write_bytes(b"never read: the config is checked first")
    return path


@pytest.fixture(scope="module")
def two_clip_root(tmp_path_factory):
    root = tmp_path_factory.mktemp("dualtalk")
    write_dualtalk_split(root, split="train", clips=2, seed=0, progress=False)
    return root


def test_a_validation_fraction_that_leaves_no_training_clip_is_refused_before_training(two_clip_root, tmp_path,
                                                                                      capsys):
    out = tmp_path / "tok.pt"
    with pytest.raises(SystemExit) as exc:
        main(["train", "sfms-tokenizer", "--dataset", "dualtalk", "--data", str(two_clip_root), "--val-frac", "0.9",
              "--export", str(out)])
    err = capsys.readouterr().err
    assert exc.value.code == 2
    assert err.strip() == "error: --val-frac 0.9 holds out all 2 clips; none is left to train on"
    assert not out.exists()


@pytest.mark.parametrize("contexts,message", [
    ("0,-3", "-3 not in the range x>=0"),
    ("a,b", "expected comma-separated integers, got 'a,b'"),
    (",", "needs at least one value"),
])
def test_sweep_contexts_are_integers_of_at_least_zero(contexts, message, tmp_path, capsys):
    with pytest.raises(SystemExit) as exc:
        main(["sweep", "--models", "zero", "--contexts", contexts, "--out", str(tmp_path / "r")])
    err = capsys.readouterr().err
    assert exc.value.code == 2 and message in err and "Traceback" not in err
    assert not (tmp_path / "r").exists()
