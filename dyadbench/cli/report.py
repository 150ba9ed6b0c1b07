"""``dyadbench report``: the results page (RESULTS.md) from result files and benchmark result files."""

from __future__ import annotations

from pathlib import Path

import click

from dyadbench import atomic
from dyadbench.cli.leaderboard import PAPER_ROWS
from dyadbench.outputs import check_file
from dyadbench.results_page import relative_command, render_page


@click.command()
@click.argument("results", nargs=-1, type=click.Path(exists=True, path_type=Path))
@click.option("--benchmarks", type=click.Path(exists=True, file_okay=False, path_type=Path),
              default=Path("benchmarks/results"), show_default=True,
              help="Folder of benchmark result files (NAME.json / NAME.md of benchmarks/output.py).")
@click.option("--out", type=click.Path(dir_okay=False, path_type=Path), default=Path("RESULTS.md"),
              show_default=True, help="Markdown page to write (atomically).")
@click.option("--paper", multiple=True, type=click.Path(exists=True, dir_okay=False, path_type=Path),
              help="Published-rows CSV to include (repeatable). Default: leaderboards/paper_timar.csv.")
@click.option("--no-paper", is_flag=True, help="Leave published rows out.")
def report(results: tuple[Path, ...], benchmarks: Path, out: Path, paper: tuple[Path, ...], no_paper: bool) -> None:
    """Write the results page from RESULTS (result files or folders; default: results/).

    \b
    The page holds every leaderboard table (all columns of `dyadbench leaderboard`'s wide tables, one
    table per suite and setting) and every benchmark result in --benchmarks, each naming its source
    files and the command that regenerates them. It has no timestamps, so the same files give the same
    bytes: commit it beside the results and regenerate it with the command it names.
    """
    check_file(out, f"--out {out}")
    sources = list(results) or [Path("results")]
    papers = [] if no_paper else (list(paper) or ([PAPER_ROWS] if PAPER_ROWS.is_file() else []))
    page = render_page(sources, benchmarks, papers, relative_command(sources, benchmarks, out, no_paper))
    atomic.write_text(out, page)
    click.echo(f"wrote {out}")
