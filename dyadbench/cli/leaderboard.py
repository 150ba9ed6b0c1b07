"""``dyadbench leaderboard``: CSV (and LaTeX) leaderboards from result files only."""

from __future__ import annotations

from pathlib import Path

import click

from dyadbench.leaderboard import long_table, table_texts, write_tables
from dyadbench.leaderboard_uncertainty import MODES
from dyadbench.outputs import check_folder
from dyadbench.paper_table import table1_texts
from dyadbench.results import result_files
from dyadbench.staleness import STALE, UNVERIFIED, Checker, check_files

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
@click.option("--uncertainty", type=click.Choice(list(MODES)), default="none", show_default=True,
              help="Add each result's recorded uncertainty to the wide tables: se = <col>_se columns "
                   "(value ± se in LaTeX), ci = <col>_ci_low/<col>_ci_high (value [low, high] in LaTeX); "
                   "empty for results recorded without it and for published rows.")
@click.option("--table1", is_flag=True,
              help="Also write TIMAR's Table 1 layout (dyadbench.paper_table): OUT/table1_<source>_<dataset>"
                   ".csv/.md/.tex for the result files and for the published rows; rows without a result are "
                   "shown as missing and listed on stderr.")
def leaderboard(results: tuple[Path, ...], out: Path, paper: tuple[Path, ...], no_paper: bool, latex: bool,
                uncertainty: str, table1: bool) -> None:
    """Build leaderboards from RESULTS (result files or folders; default: results/).

    \b
    Writes (atomically, as one set; tables of earlier builds that are not part of this one, e.g. of a
    suite no longer present or .tex without --latex, are removed, so OUT holds exactly this build):
      OUT/long.csv            one row per source/model/dataset/split/protocol/context/metric,
                              raw and publication-scaled values, oracle flag, source=dyadbench|paper
      OUT/<suite>_wide.csv    the paper table layout (scaled as printed), ranked by the suite's primary
                              column in its direction, only among rows scored on the same predictions
                              (rank_group: items, clips, data digest); oracle rows are marked and never
                              ranked
      OUT/<suite>_wide.tex    with --latex
      OUT/table1_*.csv/.md/.tex  with --table1: TIMAR's Table 1 layout (contexts offline, n = 0, 3, 7 on
                              test and ood; dualtalk, timar, timar-stream and the relative change of each
                              TIMAR row against dualtalk per column), and the same for the published
                              rows; written with the set, never removed by a build without --table1
    Numbers come only from result files written by `dyadbench eval` / `dyadbench sweep` and from the
    transcribed published rows.
    Each result file's provenance is compared with the current code and data (dyadbench.staleness):
    stale rows (a model version, weights digest or data digest that differs) are warned about on
    stderr, with a count of the rows that could not be fully compared; the tables are the same either way.
    A RESULTS folder without result files is an error (nothing is written).
    """
    check_folder(out, f"--out {out}")
    sources = list(results) or [Path("results")]
    papers = [] if no_paper else (list(paper) or ([PAPER_ROWS] if PAPER_ROWS.is_file() else []))
    long = long_table(sources, papers)
    tables = table_texts(long, latex, uncertainty)
    table1, missing = table1_texts(long) if table1 else ({}, [])
    written, removed = write_tables(out, {**tables, **table1})
    n_dyad = int((long["source"] == "dyadbench").sum())
    click.echo(f"{n_dyad} dyadbench rows, {len(long) - n_dyad} published rows")
    for path in written:
        click.echo(f"wrote {path}")
    for path in removed:
        click.echo(f"removed {path} (not part of this build)")
    for row in missing:
        click.echo(f"missing Table 1 row (shown as missing): {row}", err=True)
    warn_stale(sources)


def warn_stale(sources: list[Path]) -> None:
    """On stderr: one warning per stale result file (file, model, what differs) and the number of
    unverified ones. Never generates data: a run needing an embedded split not in the cache is unverified."""
    verdicts = check_files(result_files(sources), Checker(generate=False))
    for verdict in verdicts:
        if verdict.status == STALE:
            click.echo(f"warning: stale row {verdict.line()}; `dyadbench sweep --stale --out <its results "
                       f"folder>` re-runs it", err=True)
    unverified = sum(v.status == UNVERIFIED for v in verdicts)
    if unverified:
        click.echo(f"{unverified} of {len(verdicts)} result rows unverified: their provenance could not be "
                   f"fully compared here (e.g. written before results recorded their data digest)", err=True)
