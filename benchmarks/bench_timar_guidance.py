"""Classifier-free guidance scale of the shipped TIMAR models, against the trivial baselines, per split.

TIMAR's published runs sample with guidance off (scale 1). Guidance s mixes the conditional and the
null-user predictions of the diffusion head, x0 = u + s·(c − u), so s > 1 leans harder on the partner's
(user's) speech and motion; the agent's own speech is never dropped, so it does not amplify what drives
the jaw. This benchmark runs `timar` and `timar-stream` at each scale, and the non-oracle baselines, on
the first N dialogues of the val, test and ood splits (the same clips for every row) at one context n,
and prints FD / P-FD / MSE for exp, jaw and pose (publication scaling) with each row's verdict against
the best baseline of its split. Val and test draw people from the training population, ood from the
unseen, livelier one (see `dyadbench.synth.styles`), so the table shows whether a scale chosen on val
carries over to unseen people.

    python benchmarks/bench_timar_guidance.py            # writes benchmarks/results/timar_guidance.md
"""

from __future__ import annotations

import sys
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import click

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from output import write_result  # noqa: E402  (benchmarks/output.py)
from dyadbench.cli.eval import open_splits, run_one  # noqa: E402
from dyadbench.protocol.config import ProtocolConfig  # noqa: E402

MODELS = ("timar", "timar-stream")
BASELINES = ("mean-frame", "random", "mime", "lagged-mirror", "nn-retrieval")
KEYS = [f"{m}_{c}" for m in ("fd", "pfd", "mse") for c in ("exp", "jaw", "pose")]
HEADERS = [f"{m} {c}" for m in ("FD", "P-FD", "MSE") for c in ("exp", "jaw", "pose")]
OUT = Path(__file__).resolve().parent / "results" / "timar_guidance.md"


def _run(job: tuple[str, str, float, int, int, int]) -> tuple[str, str, float, dict[str, float], int]:
    """One eval: (model, split, scale, context, clips, seed) -> (model, split, scale, scaled metrics, items)."""
    model, split, scale, context, clips, seed = job
    source, train = open_splits(None, "synthetic", split)
    config = ProtocolConfig(context=context, seed=seed)
    result = run_one(model, source, train, config, cfg_scale=scale, weights=None, clips=clips, jobs=1,
                     predictions_dir=None, threads=1)
    return model, split, scale, {k: result.scaled[k] for k in KEYS}, result.data.items


def _verdicts(row: dict[str, float], best: dict[str, float]) -> str:
    """Which of FD / P-FD exp, jaw, pose (and MSE jaw) beat the split's best baseline."""
    checked = [f"fd_{c}" for c in ("exp", "jaw", "pose")] + [f"pfd_{c}" for c in ("exp", "jaw", "pose")] + ["mse_jaw"]
    header = dict(zip(KEYS, HEADERS))
    lost = [header[k] for k in checked if row[k] >= best[k]]
    return "beats all" if not lost else "loses on " + ", ".join(lost)


def render(rows: list[tuple[str, str, float, dict[str, float], int]], splits: list[str], context: int,
           clips: int, seed: int) -> str:
    lines = ["# TIMAR guidance scale on the embedded corpus", "",
             f"Produced by `python benchmarks/bench_timar_guidance.py` (shipped tiny checkpoints, first {clips} "
             f"dialogues of each split = both directions, n = {context}, sampling seed {seed}, 1 CPU thread per "
             "run; publication scaling: jaw ×10³, pose ×10², MSE exp ×10). `best baseline` is, per column, the "
             "lowest of the non-oracle baselines " + ", ".join(BASELINES) + "; the verdict lists the FD / P-FD "
             "columns and MSE jaw where a row does not beat it.", ""]
    for split in splits:
        part = [r for r in rows if r[1] == split]
        items = part[0][4]
        lines += [f"## {split} ({items} predictions)", "",
                  "| model | scale | " + " | ".join(HEADERS) + " | verdict |",
                  "|---|---|" + "---|" * len(HEADERS) + "---|"]
        base = [r for r in part if r[0] in BASELINES]
        best = {k: min(r[3][k] for r in base) for k in KEYS}
        for model, _, scale, metrics, _ in sorted(part, key=lambda r: (r[0] in BASELINES, r[0], r[2])):
            cells = " | ".join(f"{metrics[k]:.3f}" for k in KEYS)
            verdict = _verdicts(metrics, best) if model in MODELS else ""
            lines.append(f"| {model} | {scale if model in MODELS else '–'} | {cells} | {verdict} |")
        lines.append("| best baseline | – | " + " | ".join(f"{best[k]:.3f}" for k in KEYS) + " | |")
        lines.append("")
    return "\n".join(lines)


@click.command(help=__doc__)
@click.option("--scales", default="1,1.5,2,2.5", show_default=True, help="Comma-separated guidance scales.")
@click.option("--splits", default="val,test,ood", show_default=True)
@click.option("--context", default=7, show_default=True, type=int)
@click.option("--clips", default=20, show_default=True, type=int, help="First N dialogues of each split.")
@click.option("--seed", default=0, show_default=True, type=int, help="Sampling seed (recorded in the table).")
@click.option("--jobs", default=2, show_default=True, type=int, help="Parallel eval processes.")
@click.option("--out", default=OUT, show_default=True, type=click.Path(dir_okay=False, path_type=Path))
def main(scales: str, splits: str, context: int, clips: int, seed: int, jobs: int, out: Path) -> None:
    split_list = splits.split(",")
    scale_list = [float(s) for s in scales.split(",")]
    jobs_list = [(m, sp, s, context, clips, seed) for sp in split_list for m in MODELS for s in scale_list]
    jobs_list += [(b, sp, 1.0, context, clips, seed) for sp in split_list for b in BASELINES]
    rows = []
    with ProcessPoolExecutor(max_workers=jobs) as pool:
        for done, row in enumerate(pool.map(_run, jobs_list), 1):
            click.echo(f"[{done}/{len(jobs_list)}] {row[0]} {row[1]} scale {row[2]}: FD exp {row[3]['fd_exp']:.3f}",
                       err=True)
            rows.append(row)
    text = render(rows, split_list, context, clips, seed)
    write_result(out, text, seed=seed)
    click.echo(text)
    click.echo(f"wrote {out}", err=True)


if __name__ == "__main__":
    main()
