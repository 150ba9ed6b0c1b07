"""StyGazeTalk velocity-loss ablation (SE-64 vs SE-64-VEL) over ten seeds, under three checkpoint selections.

The paper's ablation direction is that adding the velocity loss moves FixRatio toward the ground truth.
`bench_stygazetalk_variants.py` runs it over three seeds; this script repeats it over seeds 0-9 on the 16
embedded train sessions, with the spec's selection (lowest validation L_gen, D27), with the lowest validation
L_mse alone (one criterion for both arms, so the selection does not change with the loss being ablated) and
with the final weights, and reports paired per-seed differences (with − without). Every generator uses the
shipped SE-64 style encoder (the CE evaluator), mean decoding, and is streamed over the synthetic test
sessions (n = 7).

    python benchmarks/bench_stygazetalk_velocity.py --jobs 2     # ~50 trainings of ~35 s each
    python benchmarks/bench_stygazetalk_velocity.py --reuse      # re-score checkpoints already in --work
Writes benchmarks/results/stygazetalk_velocity.md.
"""

from __future__ import annotations

import sys
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import click
import torch

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_stygazetalk_variants import (  # noqa: E402
    ABLATION, ABLATION_LABELS, DATASET, _ablation_cells, _ablation_key, _arrays, _direction, _paired, _stream,
    train_ablation_arm)
from output import write_result  # noqa: E402  (benchmarks/output.py)
from dyadbench.protocol.config import ProtocolConfig  # noqa: E402
from dyadbench.protocol.interface import ModelOptions  # noqa: E402
from dyadbench.registry import DATASETS  # noqa: E402
from dyadbench.scoring.gaze import score_arrays  # noqa: E402
from models.stygazetalk.checkpoints import SHIPPED_STYLE_ENCODER  # noqa: E402
from models.stygazetalk.config import get_generator_config  # noqa: E402

RESULT = Path(__file__).parent / "results" / "stygazetalk_velocity.md"
SELECTIONS = ("val-loss", "val-mse", "last")


def _trained_selection(variant: str, selection: str) -> str:
    """The selection whose checkpoint serves (variant, selection): at λ = 1, L_gen is L_mse exactly, so
    val-mse keeps the same weights as val-loss and is not trained twice."""
    same = selection == "val-mse" and get_generator_config(f"tiny-{variant}").lam == 1.0
    return "val-loss" if same else selection


def _checkpoints(work: Path, seeds: list[int], reuse: bool, jobs: int) -> dict[str, Path]:
    """Checkpoint of every (variant, selection, seed), trained in ``jobs`` processes unless --reuse finds it."""
    arms = {_ablation_key(v, s, seed): (v, _trained_selection(v, s), seed)
            for v in ABLATION for s in SELECTIONS for seed in seeds}
    paths = {key: work / f"tiny-{_ablation_key(*arm)}.pt" for key, arm in arms.items()}
    trained = {_ablation_key(*arm): arm for arm in arms.values()}  # each distinct checkpoint once
    todo = [arm for key, arm in trained.items() if not (reuse and paths[key].is_file())]
    with ProcessPoolExecutor(jobs) as pool:
        for future in [pool.submit(train_ablation_arm, *arm, SHIPPED_STYLE_ENCODER, paths[_ablation_key(*arm)])
                       for arm in todo]:
            future.result()
    return paths


@click.command()
@click.option("--seeds", type=click.IntRange(min=2), default=10, show_default=True,
              help="Seeds 0..N-1 per arm (paired differences need at least 2).")
@click.option("--work", type=click.Path(file_okay=False, path_type=Path), default=Path("runs/stygazetalk-velocity"),
              show_default=True, help="Folder for the trained checkpoints.")
@click.option("--reuse", is_flag=True, help="Re-use checkpoints already in --work instead of retraining.")
@click.option("--jobs", type=click.IntRange(min=1), default=1, show_default=True, help="Training processes.")
@click.option("--context", default=7, show_default=True, help="Protocol context n (history turns).")
@click.option("--out", type=click.Path(dir_okay=False, path_type=Path), default=RESULT, show_default=True)
def main(seeds: int, work: Path, reuse: bool, jobs: int, context: int, out: Path) -> None:
    """Train, stream and score the velocity-loss ablation; print and write the table."""
    torch.set_num_threads(1)
    work.mkdir(parents=True, exist_ok=True)
    seed_list = list(range(seeds))
    paths = _checkpoints(work, seed_list, reuse, jobs)
    clips = list(DATASETS.load(DATASET)(None, "test"))
    config = ProtocolConfig(context=context, seed=0)
    gt = score_arrays(_arrays(clips, [c.participants[0].motion for c in clips]), seed=0).metrics
    scored = {path: score_arrays(_stream("stygazetalk", ModelOptions(weights=path), clips, config), seed=0).metrics
              for path in set(paths.values())}
    metrics = {key: scored[path] for key, path in paths.items()}
    lines = ["# StyGazeTalk velocity-loss ablation over seeds", "",
             f"Command: `python benchmarks/bench_stygazetalk_velocity.py --seeds {seeds} --context {context}`; "
             f"tiny SE-64 and SE-64-VEL (λ = 0.5) generators, seeds 0–{seeds - 1}, trained on the 16 embedded train "
             "sessions with the shipped SE-64 style encoder; mean decoding; streamed over the synthetic test "
             f"sessions (n = {context}; the 50-frame seed window excluded). GT FixRatio {gt['fix_ratio']:.3f} "
             "(paper, HAGE: SE-64 69.22 % → SE-64-VEL 67.33 %, GT 61.13 %).", "",
             "| variant | selection | FixRatio per seed | mean FixRatio | mean CompScore | mean Sim_seq |",
             "|---|---|---|---|---|---|"]
    summary = ["", "| selection | Δ FixRatio (VEL − SE-64), mean ± s.e. | seeds lower with VEL | direction |",
               "|---|---|---|---|"]
    for selection in SELECTIONS:
        runs = {v: [metrics[_ablation_key(v, selection, seed)] for seed in seed_list] for v in ABLATION}
        lines += [f"| {label} | {selection} | {_ablation_cells(runs[v])} |" for v, label in ABLATION_LABELS]
        mean, se, lower = _paired(runs["se64"], runs["se64-vel"])
        summary.append(f"| {selection} | {mean:+.3f} ± {se:.3f} ({mean / se:+.1f} s.e.) | {lower} of {seeds} | "
                       f"{_direction(runs['se64'], runs['se64-vel'], gt['fix_ratio'])} |")
    text = "\n".join(lines + summary) + "\n"
    click.echo(text)
    write_result(out, text, seed=seed_list)


if __name__ == "__main__":
    main()
