"""``dyadbench compare A B``: paired differences between two runs on the same items, with uncertainty."""

from __future__ import annotations

import io
from pathlib import Path

import click

from dyadbench import atomic
from dyadbench.cli.options import SEED, real
from dyadbench.compare import compare, frame, load_run, text_table
from dyadbench.outputs import check_folder
from dyadbench.uncertainty import LEVEL, RESAMPLES


@click.command(name="compare")
@click.argument("a", type=click.Path(exists=True, path_type=Path))
@click.argument("b", type=click.Path(exists=True, path_type=Path))
@click.option("--out", "out", type=click.Path(file_okay=False, path_type=Path), default=None,
              help="Write DIR/compare.json and DIR/compare.csv (atomically).")
@click.option("--seed", default=0, show_default=True, type=SEED, help="Seed of the cluster bootstrap.")
@click.option("--resamples", default=RESAMPLES, show_default=True, type=click.IntRange(min=100),
              help="Bootstrap resamples of the dialogues.")
@click.option("--level", default=LEVEL, show_default=True, type=real(0.5, 1.0, max_open=True),
              help="Confidence level of the intervals.")
def compare_command(a: Path, b: Path, out: Path | None, seed: int, resamples: int, level: float) -> None:
    """Paired differences B − A per metric column over the items both runs scored.

    \b
    A, B: result.json files of `dyadbench eval` or `dyadbench score --out` (with per-clip metrics), an
    older `score` results.json (its per_clip.csv beside it), or the output folders holding them; the same
    suite and the same items.
    Per column: mean A, mean B, mean difference B − A with its cluster-robust standard error, a seeded
    bootstrap CI resampling dialogues (both directions of a dialogue together), a paired t-test p-value,
    and which run is better by the column's direction when the CI excludes 0.
    """
    if out is not None:
        check_folder(out, f"--out {out}")
    comparison = compare(load_run(a), load_run(b), seed=seed, resamples=resamples, level=level)
    click.echo(text_table(comparison))
    if out is not None:
        buf = io.StringIO()
        frame(comparison).to_csv(buf, index=False, float_format="%.10g")
        written = atomic.write_texts({out / "compare.json": atomic.to_json(comparison),
                                      out / "compare.csv": buf.getvalue()})
        click.echo("wrote " + " and ".join(map(str, written)))
