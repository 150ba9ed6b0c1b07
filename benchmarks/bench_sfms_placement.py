"""Does keyframe placement pay on the embedded corpus, and does a trained SFMS tokenizer use it?

Why dynamic keyframes lose to static ones in `bench_sfms_keyframes.py`, measured in two parts on the same
z-scored 48-frame test windows:

1. Placement oracle on exact frames (`models.sfms.placement`; no quantiser, no network): piecewise-linear
   interpolation through k true frames, for the static positions i·⌊T/k⌋ and for the best k positions
   (exact dynamic programme). static / optimal > 1 is what placement alone can give on this data.
2. A trained tokenizer (default: the shipped SFMS checkpoint's; `--tokenizer PATH` for another): its
   reconstruction MSE with its own deterministic keyframes, with the static positions and with seeded random
   k-subsets swapped in (same network), and how its keyframes are spaced (gaps between consecutive ones).

    python benchmarks/bench_sfms_placement.py            # writes benchmarks/results/sfms_placement.md
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import click
import numpy as np
import torch

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_sfms_keyframes import load_corpus  # noqa: E402
from output import write_result  # noqa: E402  (benchmarks/output.py)
from models.sfms.bundle import load_tokenizer  # noqa: E402
from models.sfms.placement import interpolation_mse, optimal_placement_mse  # noqa: E402
from models.sfms.registry import shipped  # noqa: E402
from models.sfms.topk import static_mask  # noqa: E402

RESULT = Path(__file__).parent / "results" / "sfms_placement.md"
WINDOW = 48


@torch.no_grad()
def _swap_positions(tokenizer, windows: np.ndarray, seed: int) -> dict[str, float]:
    """z-space MSE of one network with its own, the static and random keyframe positions."""
    m = torch.as_tensor(windows)
    k = tokenizer.cfg.keyframes
    gen = torch.Generator().manual_seed(seed)
    random = torch.zeros(len(m), WINDOW)
    for row in random:
        row[torch.randperm(WINDOW, generator=gen)[:k]] = 1.0
    masks = {"own": tokenizer.select(m), "static": static_mask(len(m), WINDOW, k), "random": random}
    out = {}
    for name, hard in masks.items():
        zq, _, _ = tokenizer.quantize(tokenizer.encode_keyframes(m, hard), hard)
        out[name] = float((tokenizer.inpaint(zq, hard, hard) - m).pow(2).mean())
    gaps = np.concatenate([np.diff(np.flatnonzero(h)) for h in masks["own"].numpy()])
    out["gap1"] = float(np.mean(gaps == 1))
    out["gap_median"] = float(np.median(gaps))
    return out


@click.command()
@click.option("--ks", default="3,7,10", show_default=True, help="Keyframe counts k of the oracle.")
@click.option("--oracle-windows", type=int, default=300, show_default=True,
              help="Test windows in the oracle (the dynamic programme is O(T³d) per window).")
@click.option("--test-windows", type=int, default=1024, show_default=True, help="Test windows for the tokenizer.")
@click.option("--clips", type=int, default=200, show_default=True, help="Train dialogues for the z-scoring statistics.")
@click.option("--tokenizer", "tokenizer_path", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="SFMS tokenizer or full SFMS checkpoint [default: the shipped one].")
@click.option("--seed", type=int, default=0, show_default=True, help="Seed of the random placements.")
@click.option("--out", type=click.Path(path_type=Path), default=RESULT, show_default=True, help="Markdown to write.")
def main(ks, oracle_windows, test_windows, clips, tokenizer_path, seed, out) -> None:
    """Measure the placement oracle and the tokenizer's use of positions; print and write the tables."""
    torch.set_num_threads(1)
    started = time.perf_counter()
    _, test, mean, std = load_corpus(clips, test_windows)
    oracle_rows = []
    for k in (int(v) for v in ks.split(",")):
        static = static_mask(1, WINDOW, k)[0].numpy().nonzero()[0]
        s = np.mean([interpolation_mse(w, static) for w in test[:oracle_windows]])
        o = np.mean([optimal_placement_mse(w, k) for w in test[:oracle_windows]])
        oracle_rows.append(f"| {k} | {s:.4f} | {o:.4f} | {s / o:.2f} |")
        click.echo(oracle_rows[-1], err=True)
    path = tokenizer_path or shipped()
    tokenizer = load_tokenizer(path)
    if tokenizer.cfg.keyframe_mode != "dynamic":
        raise click.UsageError(f"{path}: keyframe_mode is {tokenizer.cfg.keyframe_mode!r}; the swap needs dynamic")
    own_norm = tokenizer.normalise(torch.as_tensor(test * std + mean)).numpy()  # the tokenizer's own D22 scaling
    swap = _swap_positions(tokenizer, own_norm, seed)
    cfg = tokenizer.cfg
    lines = [
        "# SFMS: does keyframe placement pay on the embedded corpus, and does the tokenizer use it?", "",
        f"Command: `python benchmarks/bench_sfms_placement.py --ks {ks} --oracle-windows {oracle_windows} "
        f"--test-windows {test_windows}`; z-scored (first {clips} train dialogues) non-overlapping 48-frame windows "
        "of the synthetic test split, MSE over frames and the 56 dims.", "",
        f"Placement oracle on exact frames ({min(oracle_windows, len(test))} windows; piecewise-linear interpolation "
        "through k true frames, held at the ends; no quantiser, no network):", "",
        "| k | static i·⌊T/k⌋ MSE | optimal placement MSE | static / optimal |", "|---|---|---|---|", *oracle_rows,
        "", f"Tokenizer `{path.name}` (k = {cfg.keyframes}, FSQ levels "
        f"{list(cfg.fsq_levels)}, suppression radius {cfg.suppression_radius}, {len(test)} windows in its own "
        f"normalisation, {cfg.normalisation}), the same network with keyframe positions swapped:", "",
        "| positions | MSE (z) |", "|---|---|",
        f"| own (deterministic selection of the scorer) | {swap['own']:.4f} |",
        f"| static i·⌊T/k⌋ | {swap['static']:.4f} |",
        f"| random k-subsets (seed {seed}) | {swap['random']:.4f} |",
        f"| reference: each window's exact mean frame, held (no keyframes) | "
        f"{float(np.mean((own_norm - own_norm.mean(axis=1, keepdims=True)) ** 2)):.4f} |", "",
        f"Its keyframes: {100 * swap['gap1']:.0f} % of the gaps between consecutive keyframes are 1 frame "
        f"(median gap {swap['gap_median']:.0f}).", "",
        f"Wall time {time.perf_counter() - started:.0f} s (1 torch thread).",
    ]
    text = "\n".join(lines) + "\n"
    click.echo(text)
    write_result(out, text, seed=seed)


if __name__ == "__main__":
    main()
