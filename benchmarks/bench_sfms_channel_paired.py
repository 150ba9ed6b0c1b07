"""SFMS per-channel keyframes (``sfms-channel``) against the shared mask (``sfms``), paired per item.

Both shipped corpus-v2 checkpoints stream the same first ``--clips`` dialogues of each split at context n through
the protocol (one torch thread; both directions of each dialogue), are scored with the DualTalk suite, and
:func:`dyadbench.compare.compare` gives per metric column the paired difference per-channel − shared with its
cluster-robust standard error, a bootstrap CI resampling dialogues and a paired t-test (``dyadbench compare``).

    python benchmarks/bench_sfms_channel_paired.py          # test and ood, n = 7, 20 dialogues (~4 min)
Writes benchmarks/results/sfms_channel_paired.{json,md}.
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import click

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from output import write_result  # noqa: E402  (benchmarks/output.py)
from dyadbench.cli import main as cli_main  # noqa: E402
from dyadbench.compare import compare, load_run, text_table  # noqa: E402

RESULT = Path(__file__).parent / "results" / "sfms_channel_paired.md"
SHARED, CHANNEL = "sfms", "sfms-channel"


@click.command()
@click.option("--splits", default="test,ood", show_default=True, help="Corpus v2 splits.")
@click.option("--context", default=7, show_default=True, help="Protocol context n.")
@click.option("--clips", default=20, show_default=True, help="First N dialogues of each split.")
@click.option("--seed", default=0, show_default=True, help="Protocol seed (sampling) and bootstrap seed.")
@click.option("--out", type=click.Path(dir_okay=False, path_type=Path), default=RESULT, show_default=True)
def main(splits: str, context: int, clips: int, seed: int, out: Path) -> None:
    """Stream both SFMS checkpoints, compare them paired, print and write the tables."""
    sections, data = [], {}
    with tempfile.TemporaryDirectory() as work:
        for split in splits.split(","):
            runs = {}
            for model in (SHARED, CHANNEL):
                runs[model] = Path(work) / f"{split}-{model}"
                cli_main(["eval", "--model", model, "--split", split, "--context", str(context), "--clips",
                          str(clips), "--seed", str(seed), "--threads", "1", "--out", str(runs[model])])
            comparison = {**compare(load_run(runs[SHARED]), load_run(runs[CHANNEL]), seed=seed),
                          "a": f"{SHARED} {split} n={context}", "b": f"{CHANNEL} {split} n={context}"}
            data[split] = comparison
            sections += [f"## {split} (A = {SHARED}, B = {CHANNEL})", "", "```", text_table(comparison), "```", ""]
    text = "\n".join([
        "# SFMS: per-channel keyframes against the shared mask, paired", "",
        f"Shipped corpus-v2 checkpoints (`sfms-tiny-v2.pt`, `sfms-tiny-channel-v2.pt`), the first {clips} dialogues "
        f"of each split, both directions, context n = {context}, protocol seed {seed}, one thread; DualTalk suite "
        "(raw units; the leaderboards scale them). B − A < 0 on an error column (FD, P-FD, MSE) means the "
        "per-channel model is better there.", "", *sections])
    click.echo(text)
    write_result(out, text, seed=seed, data={"comparisons": data, "clips": clips, "context": context})


if __name__ == "__main__":
    main()
