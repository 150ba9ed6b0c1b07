"""``dyadbench score``: score predictions on disk with one metric suite, into the result file ``eval`` writes."""

from __future__ import annotations

import sys
import time
from pathlib import Path

import click

from dyadbench import atomic
from dyadbench.cli.cluster import scheduler_option
from dyadbench.cli.options import SEED
from dyadbench.outputs import check_folder, kept_on_failure
from dyadbench.registry import SUITES
from dyadbench.scoring import policy

PREDICTION_FORMATS = """\b
PRED, per suite (a folder of .npy files, or one .npz whose keys are the same names):
  dualtalk  <clip>_speaker1.npy / <clip>_speaker2.npy, float (T, 56) [exp 50 | jaw 3 | head
            rotation 3] (what TIMAR and DualTalk write); the partner of _speaker1 is _speaker2.
            GT: a DualTalk split folder of <clip>_speakerK.npz (or the root with --split).
            A clip whose partner's .npz is missing (e.g. the released demo clips) is scored on
            every metric but P-FD and rPCC, which are reported as not computable for it.
  react     one (10, T, 25) array of reactions per sample, named by the sample's speaker path
            (NoXI/<session>/Expert_video/3.npy, in sub-folders), or one .npz holding
            'predictions' (N, 10, T, 25) in the split csv's mirrored order. GT: a REACT root.
  l2l       <host>_<split>_<n:05d>_listener.npy, float (T, 56) as for dualtalk.
            GT: a Learning2Listen root (or one host's folder); split test by default.
  gaze      <clip>_subject.npy (or <clip>.npy), float (T, 7) in degrees.
            GT: a gaze-head root or split folder.
  seamless  <participant file stem>.npy (V.._S.._I.._P..), float (T, 166) in the split's movement
            layout (168 with gaze). GT: a Seamless Interaction root; --split test or <label>/test.
"""


def default_model_name(pred: Path) -> str:
    """The name PRED's scores are ranked under when --model is not given: PRED's name without suffix, or its
    parent's when PRED is an ``eval --out`` folder's ``predictions/``."""
    pred = pred.resolve()
    return pred.parent.name if pred.name == "predictions" else pred.stem


@click.command(epilog=PREDICTION_FORMATS)
@click.argument("pred", type=click.Path(exists=True, path_type=Path))
@click.option("--gt", "gt", required=True, type=click.Path(exists=True, path_type=Path),
              help="Ground truth: a DualTalk split folder (dualtalk), a REACT root (react), an L2L root "
                   "(l2l), a gaze-head root or session folder (gaze) or a Seamless Interaction root (seamless).")
@click.option("--suite", default="dualtalk", show_default=True, type=click.Choice(SUITES.names()),
              help="Metric suite. dualtalk = DualTalk/TIMAR tables; react = REACT challenge; "
                   "l2l = Learning2Listen line; gaze = StyGazeTalk gaze-head suite; seamless = Seamless "
                   "Interaction suite (invalid movement frames excluded).")
@click.option("--split", default=None,
              help="Split name where the ground truth root holds several (dualtalk: test/ood sub-folder "
                   "of the DualTalk root; react: val/test; l2l: test; gaze: a split folder; seamless: "
                   "train/dev/test of both labels, or one label's as improvised/test or naturalistic/test; "
                   "default test). Recorded in the result (default: the split the suite scored, else GT's "
                   "folder name).")
@click.option("--model", "model", default=None,
              help="Name of the model that made PRED: the row it is ranked under by `dyadbench leaderboard` "
                   "(nothing is run). Default: PRED's name (its parent's for an eval folder's predictions/).")
@click.option("--out", "out", type=click.Path(file_okay=False, path_type=Path), default=None,
              help="Write DIR/result.json (the typed result eval writes, protocol 'external predictions', "
                   "ready for `dyadbench leaderboard DIR`) and DIR/per_clip.csv, atomically.")
@click.option("--jobs", "-j", default=1, show_default=True, type=click.IntRange(min=1),
              help="Worker processes for per-clip metrics (with --scheduler: tasks on the cluster).")
@click.option("--strict", is_flag=True,
              help="Exit non-zero when any expected prediction is missing or excluded (NaN/inf values, too "
                   "few frames). Predictions without ground truth are listed, never fatal.")
@click.option("--seed", default=0, show_default=True, type=SEED,
              help="Seed for the randomised metrics (diversity index draws); recorded in the result.")
@click.option("--oracle", is_flag=True,
              help="PRED copies the ground truth (e.g. REACT's GT baseline): recorded in the result, so the "
                   "leaderboard marks the row and never ranks it.")
@scheduler_option
def score(pred: Path, gt: Path, suite: str, split: str | None, model: str | None, out: Path | None, jobs: int,
          strict: bool, seed: int, oracle: bool) -> None:
    """Score PRED against ground truth GT with the metrics of the published scripts.

    By default the predictions present are scored and coverage is reported; --strict fails on gaps.
    The accepted prediction formats of every suite are listed below.
    """
    from dyadbench.results import external_result  # noqa: PLC0415  (keeps --help light)

    if out is not None:
        check_folder(out, f"--out {out}")
    started = time.perf_counter()
    report = SUITES.load(suite)(pred, gt, split=split, jobs=jobs, seed=seed)
    click.echo(f"[{suite}] {report.coverage_line()}")
    for note in report.notes:  # warnings (implausible values, named by file) go to stderr
        warning = note.startswith(policy.WARNING)
        click.echo(note if warning else f"note: {note}", err=warning)
    click.echo(report.table())
    if out is not None:
        result = external_result(report, model=model or default_model_name(pred), dataset=suite,
                                 split=split or report.config.get("split") or Path(gt).resolve().name,
                                 root=str(gt), predictions=str(pred),
                                 wall_s=time.perf_counter() - started, seed=seed, oracle=oracle)
        with kept_on_failure(out / "result.json", lambda: atomic.to_json(result.to_dict())):
            json_path = result.write(out / "result.json")
            csv_path = report.write_per_item(out / "per_clip.csv")
        click.echo(f"wrote {json_path} and {csv_path}")
    if strict and not report.complete:
        click.echo("error: --strict: predictions are missing or were excluded (see above)", err=True)
        sys.exit(1)
