"""``dyadbench data``: generate synthetic splits in a dataset layout, validate folders, describe them."""

from __future__ import annotations

import sys
from pathlib import Path

import click

from dyadbench.atomic import to_json
from dyadbench.cli.options import SEED
from dyadbench.datasets.layouts import LAYOUTS, get_layout

LAYOUT_HELP = "Dataset layout: " + "; ".join(f"{name} = {layout.summary}" for name, layout in LAYOUTS.items())


@click.group()
def data() -> None:
    """Generate, validate and describe datasets.

    \b
    Examples:
      dyadbench data synth --out synth/ --split test --clips 20
      dyadbench data validate DualTalk/test
      dyadbench data info DualTalk/ood
    """


@data.command()
@click.option("--out", "out", required=True, type=click.Path(file_okay=False, path_type=Path),
              help="Root folder to write; the split goes into OUT/<split>/ (dualtalk: flat "
                   "<clip>_speaker{1,2}.wav/.npz plus synthetic.json with the generator's annotations).")
@click.option("--layout", default="dualtalk", show_default=True, type=click.Choice(list(LAYOUTS)),
              help=LAYOUT_HELP)
@click.option("--split", default="test", show_default=True,
              help="Split to generate. dualtalk: train, test, ood (unseen people and turn statistics) or "
                   "val; the other layouts name theirs in their own terms (react: val, test; l2l: train, test).")
@click.option("--clips", "clips", default=None, type=click.IntRange(min=1),
              help="Number of dialogues (sessions). Default: the split's standard size "
                   "(dualtalk: test 533, ood 377, train 800). Clip i is the same whatever the count.")
@click.option("--seed", default=0, show_default=True, type=SEED,
              help="Generator seed; the same seed writes byte-identical files.")
@click.option("--jobs", "-j", default=1, show_default=True, type=click.IntRange(min=1),
              help="Worker processes (the files do not depend on it).")
@click.option("--force", is_flag=True,
              help="Replace the split folder even when it holds files the generator did not write.")
def synth(out: Path, layout: str, split: str, clips: int | None, seed: int, jobs: int, force: bool) -> None:
    """Write a synthetic split of the embedded conversation corpus in LAYOUT.

    The split folder is written aside and swapped in when complete: a previously generated split there
    is replaced whole (never mixed with the new clips), and an interrupted run leaves it untouched. A
    split folder holding other files is refused unless --force.
    """
    summary = get_layout(layout).write(out, split=split, clips=clips, seed=seed, jobs=jobs, force=force)
    click.echo(to_json(summary), nl=False)


@data.command()
@click.argument("folder", type=click.Path(exists=True, file_okay=False, path_type=Path))
@click.option("--layout", default="dualtalk", show_default=True, type=click.Choice(list(LAYOUTS)),
              help=LAYOUT_HELP)
def validate(folder: Path, layout: str) -> None:
    """Check FOLDER (a split folder or a root holding train/ test/ ood/) and report every problem.

    \b
    dualtalk checks: every dialogue has <clip>_speaker1 and _speaker2 .wav and .npz; npz keys exp (T,50)
    and pose (T,6) (shape, tex, cam, light: warned when absent), float dtype, finite values; wavs are
    readable 16 kHz mono with finite samples; audio and motion durations agree within 0.1 s.
    Exits with status 1 when any error is found.
    """
    report = get_layout(layout).validate(folder)
    click.echo(report.summary())
    if not report.ok:
        sys.exit(1)


@data.command()
@click.argument("folder", type=click.Path(exists=True, file_okay=False, path_type=Path))
@click.option("--layout", default="dualtalk", show_default=True, type=click.Choice(list(LAYOUTS)),
              help=LAYOUT_HELP)
def info(folder: Path, layout: str) -> None:
    """Print split statistics of FOLDER as JSON.

    \b
    dualtalk: dialogues (complete / incomplete), hours, frames, clip lengths, and from an energy VAD
    (frame RMS above the midpoint between the 10th and 95th level percentiles, gaps < 0.3 s filled,
    runs < 0.12 s dropped) the talk fraction, overlap / union of talking and turn counts (a turn changes
    when a segment of >= 1 s by the other participant starts); the mean per-participant motion
    statistics (expression / head / jaw spread and speed, jaw-speech correlation), the quantities the
    synthetic corpus is calibrated on.
    """
    click.echo(to_json(get_layout(layout).describe(folder)), nl=False)
