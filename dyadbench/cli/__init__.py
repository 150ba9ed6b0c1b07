"""The ``dyadbench`` command line.

Sub-commands live in their own modules and are imported only when invoked, so ``dyadbench --help``
and ``dyadbench models`` stay fast and never import torch.
"""

from __future__ import annotations

import sys
import warnings

import click

from dyadbench import __version__
from dyadbench.cli.lazy import lazy_group
from dyadbench.errors import DyadbenchError

# command name -> ("module:attribute", one-line help)
COMMANDS: dict[str, tuple[str, str]] = {
    "score": ("dyadbench.cli.score:score", "Score predictions on disk against ground truth."),
    "data": ("dyadbench.cli.data:data", "Generate, validate and describe datasets."),
    "eval": ("dyadbench.cli.eval:eval_command", "Run a model through the streaming protocol and score it."),
    "sweep": ("dyadbench.cli.sweep:sweep", "Evaluate models over splits and contexts, one result file each."),
    "train": ("dyadbench.cli.train:train", "Train a reference model (TIMAR, SFMS, StyGazeTalk)."),
    "leaderboard": ("dyadbench.cli.leaderboard:leaderboard", "Build CSV/LaTeX leaderboards from result files."),
    "report": ("dyadbench.cli.report:report", "Write the results page (RESULTS.md) from result and benchmark files."),
    "compare": ("dyadbench.cli.compare:compare_command", "Paired differences between two runs, with uncertainty."),
    "plot": ("dyadbench.cli.plot:plot", "Plot trajectories and metric-vs-context curves."),
    "robustness": ("dyadbench.cli.robustness:robustness",
                   "Robustness sweep: perturbed partner motion and speech, degradation table and plot."),
    "weights": ("dyadbench.cli.weights:weights", "Convert released checkpoints into native dyadbench files."),
    "models": ("dyadbench.cli.listing:models", "List registered models and baselines."),
    "datasets": ("dyadbench.cli.listing:datasets", "List registered datasets and metric suites."),
}


@click.group(cls=lazy_group(COMMANDS), context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="dyadbench")
def cli() -> None:
    """dyadbench: score dyadic head-motion models exactly as the published metric scripts do.

    \b
    Typical use:
      dyadbench eval --model timar --split ood --context 7
      dyadbench score preds/ --gt DualTalk/test --out results/
      dyadbench leaderboard
    Run `dyadbench COMMAND --help` for the options of each command.
    """


def main(argv: list[str] | None = None) -> None:
    """Entry point: user-facing errors are printed as one line of their own (after any progress bar), without
    a traceback; warnings of this process are collected and printed as one summary line per kind at the end
    (:func:`warning_summary`), e.g. the LinAlgWarnings of constant predictions."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", RuntimeWarning)  # counted, not shown one by one (LinAlgWarning is one)
        warnings.simplefilter("always", UserWarning)
        try:
            cli.main(args=argv, prog_name="dyadbench", standalone_mode=False)
            code, error = 0, None
        except click.exceptions.Abort:
            code, error = 130, "Aborted."
        except click.ClickException as exc:
            code, error = exc.exit_code, exc
        except DyadbenchError as exc:
            code, error = 2, f"error: {exc}"
        except click.exceptions.Exit as exc:
            code, error = exc.exit_code, None
        except SystemExit as exc:  # e.g. score --strict
            code, error = exc.code, None
        finally:
            _end_progress_bars()
            for line in warning_summary(caught):
                click.echo(line, err=True)
    if isinstance(error, click.ClickException):
        error.show()
    elif error is not None:
        click.echo(error, err=True)
    if code:
        sys.exit(code)


def warning_summary(caught: list[warnings.WarningMessage]) -> list[str]:
    """One line per kind of warning (category and message): how many times it was raised and where first."""
    kinds: dict[tuple[str, str], list[warnings.WarningMessage]] = {}
    for w in caught:
        kinds.setdefault((w.category.__name__, str(w.message)), []).append(w)
    return [f"warning: {name} x{len(ws)}: {message} (first at {ws[0].filename}:{ws[0].lineno})"
            for (name, message), ws in kinds.items()]


def _end_progress_bars() -> None:
    """Close the progress bars still open (an error stopped their loop), so what follows starts a new line."""
    tqdm = sys.modules.get("tqdm")
    for bar in list(getattr(getattr(tqdm, "tqdm", None), "_instances", ()) or ()):
        bar.close()
