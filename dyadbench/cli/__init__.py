"""The ``dyadbench`` command line.

Sub-commands live in their own modules and are imported only when invoked, so ``dyadbench --help``
and ``dyadbench models`` stay fast and never import torch.
"""

from __future__ import annotations

import sys

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
    """Entry point: user-facing errors are printed as one line, without a traceback."""
    try:
        cli.main(args=argv, prog_name="dyadbench", standalone_mode=False)
    except click.exceptions.Abort:
        click.echo("Aborted.", err=True)
        sys.exit(130)
    except click.ClickException as exc:
        exc.show()
        sys.exit(exc.exit_code)
    except DyadbenchError as exc:
        click.echo(f"error: {exc}", err=True)
        sys.exit(2)
    except SystemExit:
        raise
    except click.exceptions.Exit as exc:
        sys.exit(exc.exit_code)
