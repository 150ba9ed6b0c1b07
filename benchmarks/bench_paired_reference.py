"""Paired comparisons of the reference models against the baselines on the same predictions.

A leaderboard row's mean hides how much of a margin is noise. Here every reference model (``--models``)
is compared with every baseline (``--baselines``) prediction by prediction with
:func:`dyadbench.compare.compare`: per column the mean difference model − baseline, its cluster-robust
standard error and a seeded cluster-bootstrap 95 % CI over dialogues (both directions of a dialogue
resampled together), the paired t-test p-value and which run is better by the column's direction —
"=" when the CI includes 0, so a margin that is not significant reads as a tie.

Each run is a ``dyadbench eval`` output folder under ``--runs`` (per-clip metrics kept); a missing one
is run first (embedded corpus, ``--split`` / ``--context``, seed 0, as the committed leaderboard rows).

    python benchmarks/bench_paired_reference.py [--split test] [--context 7] [--jobs 2]
        # writes benchmarks/results/paired_reference_<split>_n<context>.{json,md}
"""

from __future__ import annotations

import argparse
import subprocess
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from dyadbench.compare import compare, load_run  # noqa: E402
from output import RESULTS, write_result  # noqa: E402  (benchmarks/output.py)

SEED = 0


def ensure_run(runs: Path, model: str, split: str, context: int, jobs: int) -> Path:
    """The eval output folder of ``model`` (run now with ``dyadbench eval`` when it has no result)."""
    folder = runs / f"{model}_{split}_n{context}"
    if not (folder / "result.json").is_file():
        subprocess.run([sys.executable, "-m", "dyadbench", "eval", "--model", model, "--split", split,
                        "--context", str(context), "--seed", str(SEED), "--jobs", str(jobs), "--threads", "1",
                        "--out", str(folder), "--force"], check=True)
    return folder


def _cell(column: dict) -> str:
    """``diff ± se [low, high]`` of one compared column, with its verdict."""
    verdict = {"A": "baseline better", "B": "model better", "=": "tie (CI includes 0)", "": "no direction"}
    return (f"{column['diff']:+.4g} ± {column['se']:.2g} [{column['ci_low']:.4g}, {column['ci_high']:.4g}], "
            f"p {column['p_value']:.2g}: {verdict[column['better']]}")


def markdown(comparisons: dict[tuple[str, str], dict], split: str, context: int) -> str:
    """One table per reference model: a row per column, a cell per baseline."""
    models = list(dict.fromkeys(m for m, _ in comparisons))
    baselines = list(dict.fromkeys(b for _, b in comparisons))
    some = next(iter(comparisons.values()))
    method = some["uncertainty_method"]
    parts = [f"# Paired comparisons, embedded corpus {split}, n = {context}",
             "",
             f"Model − baseline per column over the same {some['items']} predictions ({method['clusters']} "
             f"dialogues): mean ± cluster-robust s.e. [{method['level']:.0%} cluster-bootstrap CI, "
             f"{method['resamples']} resamples, seed {method['seed']}], paired t-test p. Raw (unscaled) "
             f"values; lower is better except where the suite declares otherwise."]
    for model in models:
        parts += ["", f"## {model}", "",
                  "| column | " + " | ".join(f"vs {b}" for b in baselines) + " |",
                  "|---|" + "---|" * len(baselines)]
        keys = [c["metric"] for c in comparisons[(model, baselines[0])]["columns"]]
        for key in keys:
            cells = [_cell(next(c for c in comparisons[(model, b)]["columns"] if c["metric"] == key))
                     for b in baselines]
            parts.append(f"| {key} | " + " | ".join(cells) + " |")
    return "\n".join(parts) + "\n"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--models", default="timar,timar-stream")
    parser.add_argument("--baselines", default="mean-frame,nn-retrieval,random")
    parser.add_argument("--split", default="test")
    parser.add_argument("--context", type=int, default=7)
    parser.add_argument("--jobs", type=int, default=2)
    parser.add_argument("--runs", type=Path, default=Path("runs") / "paired",
                        help="Folder of the eval outputs (reused when present).")
    parser.add_argument("--out", type=Path, default=None,
                        help="Result to write (.json and .md) [default: benchmarks/results/"
                             "paired_reference_<split>_n<context>].")
    args = parser.parse_args()
    models, baselines = args.models.split(","), args.baselines.split(",")
    runs = {m: load_run(ensure_run(args.runs, m, args.split, args.context, args.jobs)) for m in models + baselines}
    comparisons = {(m, b): compare(runs[b], runs[m], seed=SEED) for m in models for b in baselines}
    text = markdown(comparisons, args.split, args.context)
    print(text)
    out = args.out or RESULTS / f"paired_reference_{args.split}_n{args.context}"
    data = {f"{m} - {b}": {c["metric"]: {k: c[k] for k in ("diff", "se", "ci_low", "ci_high", "p_value", "better")}
                           for c in comparison["columns"]}
            for (m, b), comparison in comparisons.items()}
    write_result(out, text, seed=SEED, data=data)


if __name__ == "__main__":
    main()
