"""``dyadbench leaderboard``: CSV (and LaTeX) leaderboards from result files only."""

from __future__ import annotations

from pathlib import Path

import click

from dyadbench.leaderboard import long_table, table_texts, write_tables
from dyadbench.outputs import check_folder

#: Published rows shipped with dyadbench (transcribed from the TIMAR paper, Tables 1 and 2).
PAPER_ROWS = Path(__file__).resolve().parents[2] / "leaderboards" / "paper_timar.csv"


@click.command()
@click.argument("results", nargs=-1, type=click.Path(exists=True, path_type=Path))
@click.option("--out", "out", type=click.Path(file_okay=False, path_type=Path), default=Path("leaderboards"),
              show_default=True, help="Folder for long.csv, <suite>_wide.csv (and .tex with --latex).")
@click.option("--paper", "paper", multiple=True, type=click.Path(exists=True, dir_okay=False, path_type=Path),
              help="Published-rows CSV to include as source=paper (repeatable). Default: the shipped "
                   "TIMAR Tables 1-2 (leaderboards/paper_timar.csv).")
@click.option("--no-paper", is_flag=True, help="Leave published rows out.")
@click.option("--latex", is_flag=True, help="Also write a LaTeX tabular per suite.")
def leaderboard(results: tuple[Path, ...], out: Path, paper: tuple[Path, ...], no_paper: bool, latex: bool) -> None:
    """Build leaderboards from RESULTS (result files or folders; default: results/).

    \b
    Writes (atomically, as one set; tables of earlier builds that are not part of this one, e.g. of a
    suite no longer present or .tex without --latex, are removed, so OUT holds exactly this build):
      OUT/long.csv            one row per source/model/dataset/split/protocol/context/metric,
                              raw and publication-scaled values, oracle flag, source=dyadbench|paper
      OUT/<suite>_wide.csv    the paper table layout (scaled as printed), ranked by the first column;
                              oracle rows are marked and never ranked
      OUT/<suite>_wide.tex    with --latex
    Numbers come only from result files written by `dyadbench eval` / `dyadbench sweep` and from the
    transcribed published rows.
    A RESULTS folder without result files is an error (nothing is written).
    """
    check_folder(out, f"--out {out}")
    sources = list(results) or [Path("results")]
    papers = [] if no_paper else (list(paper) or ([PAPER_ROWS] if PAPER_ROWS.is_file() else []))
    long = long_table(sources, papers)
    written, removed = write_tables(out, table_texts(long, latex))
    n_dyad = int((long["source"] == "dyadbench").sum())
    click.echo(f"{n_dyad} dyadbench rows, {len(long) - n_dyad} published rows")
    for path in written:
        click.echo(f"wrote {path}")
    for path in removed:
        click.echo(f"removed {path} (not part of this build)")
