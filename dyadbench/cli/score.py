"""``dyadbench score``: score predictions on disk with one metric suite."""

from __future__ import annotations

import sys
from pathlib import Path

import click

from dyadbench import atomic
from dyadbench.cli.options import SEED
from dyadbench.outputs import check_folder, kept_on_failure
from dyadbench.registry import SUITES
from dyadbench.scoring import policy


@click.command()
@click.argument("pred", type=click.Path(exists=True, path_type=Path))
@click.option("--gt", "gt", required=True, type=click.Path(exists=True, path_type=Path),
              help="Ground truth: a DualTalk split folder (dualtalk), a REACT root (react), an L2L root "
                   "(l2l) or a gaze-head session folder (gaze).")
@click.option("--suite", default="dualtalk", show_default=True, type=click.Choice(SUITES.names()),
              help="Metric suite. dualtalk = DualTalk/TIMAR tables; react = REACT challenge; "
                   "l2l = Learning2Listen line; gaze = StyGazeTalk gaze-head suite.")
@click.option("--split", default=None,
              help="Split name where the ground truth root holds several (dualtalk: test/ood sub-folder "
                   "of the DualTalk root; react: val/test; l2l: test).")
@click.option("--out", "out", type=click.Path(file_okay=False, path_type=Path), default=None,
              help="Write DIR/results.json and DIR/per_clip.csv (atomically).")
@click.option("--jobs", "-j", default=1, show_default=True, type=click.IntRange(min=1),
              help="Worker processes for per-clip metrics.")
@click.option("--strict", is_flag=True,
              help="Exit non-zero when any expected prediction is missing or excluded (NaN/inf values, too "
                   "few frames). Predictions without ground truth are listed, never fatal.")
@click.option("--seed", default=0, show_default=True, type=SEED,
              help="Seed for the randomised metrics (diversity index draws); recorded in the result.")
def score(pred: Path, gt: Path, suite: str, split: str | None, out: Path | None, jobs: int,
          strict: bool, seed: int) -> None:
    """Score PRED against ground truth with the metrics of the published scripts.

    \b
    PRED (dualtalk suite): a folder of <clip>_speakerK.npy files, float (T, 56) ordered
    [exp 50 | jaw 3 | head rotation 3] (what TIMAR and DualTalk write), or one .npz whose keys are
    those stems. The partner of <clip>_speaker1 is <clip>_speaker2.
    By default the predictions present are scored and coverage is reported; --strict fails on gaps.
    """
    if out is not None:
        check_folder(out, f"--out {out}")
    score_paths = SUITES.load(suite)
    report = score_paths(pred, gt, split=split, jobs=jobs, seed=seed)
    click.echo(f"[{suite}] {report.coverage_line()}")
    for note in report.notes:  # warnings (implausible values, named by file) go to stderr
        warning = note.startswith(policy.WARNING)
        click.echo(note if warning else f"note: {note}", err=warning)
    click.echo(report.table())
    if out is not None:
        with kept_on_failure(out / "results.json", lambda: atomic.to_json(report.to_dict())):
            json_path, csv_path = report.write(out)
        click.echo(f"wrote {json_path} and {csv_path}")
    if strict and not report.complete:
        click.echo("error: --strict: predictions are missing or were excluded (see above)", err=True)
        sys.exit(1)
