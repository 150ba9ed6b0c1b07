"""SFMS keyframe allocation: one mask shared by all channels against per-channel keyframes (the paper's
"channel-wise tokenization with independent keyframe allocation"), at equal keyframe budget (k keyframe
values in every channel), on the embedded corpus.

Two measurements on the same z-scored non-overlapping 48-frame test windows as `bench_sfms_placement.py`:

1. Placement oracle on exact frames (`models.sfms.placement`; no quantiser, no network): piecewise-linear
   interpolation through true frames, MSE = (1/(T d)) Σ_t Σ_c (ŵ_tc − w_tc)², for the static positions
   i·⌊T/k⌋, the best shared k positions and the best k positions of every channel on its own (exact
   dynamic programmes). shared optimal / per-channel optimal is what the allocation alone can give.
2. Two tiny tokenizers trained from the same seed for the same steps (`--set`-equivalent config:
   the tiny preset with ``mask_sharing`` "frame" / "channel", the given k, batch and steps, no checkpoint
   selection: the weights after the last step), their eval-mode reconstruction MSE (z) on the test
   windows, the codes each window carries (k shared, k·d per channel) and the seconds per training step.

    python benchmarks/bench_sfms_allocation.py      # writes benchmarks/results/sfms_allocation.{json,md}
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
from models.sfms.config import tokenizer_preset  # noqa: E402
from models.sfms.placement import interpolation_mse, optimal_placement_mse, per_channel_optimal_mse  # noqa: E402
from models.sfms.topk import static_mask  # noqa: E402
from models.sfms.train_tokenizer import eval_windows, fit_tokenizer, reconstruction_mse  # noqa: E402

RESULT = Path(__file__).parent / "results" / "sfms_allocation.md"
WINDOW = 48


def oracle(test: np.ndarray, k: int) -> dict[str, float]:
    """Mean static / shared-optimal / per-channel-optimal interpolation MSE over the windows."""
    static = static_mask(1, WINDOW, k)[0].numpy().nonzero()[0]
    return {"k": k,
            "static": float(np.mean([interpolation_mse(w, static) for w in test])),
            "shared_optimal": float(np.mean([optimal_placement_mse(w, k) for w in test])),
            "per_channel_optimal": float(np.mean([per_channel_optimal_mse(w, k) for w in test]))}


def trained(train: list[np.ndarray], test: np.ndarray, sharing: str, k: int, steps: int, batch: int,
            seed: int) -> dict[str, float]:
    """Test MSE (z) of a tiny tokenizer with allocation ``sharing`` after ``steps`` steps (no selection)."""
    cfg = tokenizer_preset("tiny", keyframes=k, mask_sharing=sharing, steps=steps, batch=batch, val_every=steps)
    dim = train[0].shape[1]
    held_out = eval_windows(train[-2:], WINDOW, limit=16)  # validated once, after the last step
    started = time.perf_counter()
    model, history = fit_tokenizer(cfg, train[:-2], held_out, motion_mean=np.zeros(dim, np.float32),
                                   motion_std=np.ones(dim, np.float32), seed=seed, progress=False)
    seconds = time.perf_counter() - started
    codes = k * (dim if sharing == "channel" else 1)
    return {"allocation": sharing, "k": k, "steps": steps, "batch": batch, "codes_per_window": codes,
            "bits_per_window": codes * float(np.log2(cfg.n_codes)),
            "test_mse_z": reconstruction_mse(model, test)["mse_z"],
            "final_train_mse": history["steps"][-1]["motion"], "seconds_per_step": seconds / steps}


@click.command()
@click.option("--ks", default="3,7,10", show_default=True, help="Keyframe counts k of the oracle.")
@click.option("--oracle-windows", type=int, default=200, show_default=True, help="Test windows in the oracle.")
@click.option("--train-k", type=int, default=3, show_default=True, help="k of the two trained tokenizers.")
@click.option("--steps", type=int, default=150, show_default=True, help="Training steps of each tokenizer.")
@click.option("--batch", type=int, default=8, show_default=True, help="Windows per training step.")
@click.option("--test-windows", type=int, default=256, show_default=True, help="Test windows of the trained ones.")
@click.option("--clips", type=int, default=40, show_default=True, help="Train dialogues (statistics and training).")
@click.option("--seed", type=int, default=0, show_default=True, help="Seed of the training runs.")
@click.option("--out", type=click.Path(path_type=Path), default=RESULT, show_default=True, help="Markdown to write.")
def main(ks, oracle_windows, train_k, steps, batch, test_windows, clips, seed, out) -> None:
    """Measure both allocations; print and write the tables."""
    torch.set_num_threads(1)
    started = time.perf_counter()
    train, test, _, _ = load_corpus(clips, max(test_windows, oracle_windows))
    oracle_rows = [oracle(test[:oracle_windows].astype(np.float64), int(k)) for k in ks.split(",")]
    for row in oracle_rows:
        click.echo(row, err=True)
    runs = [trained(train, test[:test_windows], sharing, train_k, steps, batch, seed)
            for sharing in ("frame", "channel")]
    for row in runs:
        click.echo(row, err=True)
    lines = [
        "# SFMS keyframe allocation: shared mask against per-channel keyframes (equal keyframe budget)", "",
        f"Command: `python benchmarks/bench_sfms_allocation.py --ks {ks} --oracle-windows {oracle_windows} "
        f"--train-k {train_k} --steps {steps} --batch {batch} --test-windows {test_windows} --clips {clips} "
        f"--seed {seed}`; z-scored (first {clips} train dialogues) non-overlapping 48-frame windows of the "
        "synthetic test split; MSE over frames and the 56 dims.", "",
        f"Placement oracle on exact frames ({min(oracle_windows, len(test))} windows; piecewise-linear "
        "interpolation through true frames, held at the ends; k keyframe values in every channel):", "",
        "| k | static i·⌊T/k⌋ | shared optimal | per-channel optimal | shared / per-channel |",
        "|---|---|---|---|---|",
        *(f"| {r['k']} | {r['static']:.4f} | {r['shared_optimal']:.4f} | {r['per_channel_optimal']:.4f} | "
          f"{r['shared_optimal'] / r['per_channel_optimal']:.2f} |" for r in oracle_rows), "",
        f"Tiny tokenizers (tiny preset, k = {train_k}, {steps} steps of batch {batch}, seed {seed}, one run each, "
        f"weights after the last step; {min(test_windows, len(test))} test windows). Short runs: this compares "
        "early training, not converged capacity.", "",
        "| allocation | codes / window | bits / window | test MSE (z) | last train MSE | s / step |",
        "|---|---|---|---|---|---|",
        *(f"| {'shared (frame)' if r['allocation'] == 'frame' else 'per-channel'} | {r['codes_per_window']} | "
          f"{r['bits_per_window']:.0f} | {r['test_mse_z']:.4f} | {r['final_train_mse']:.4f} | "
          f"{r['seconds_per_step']:.2f} |" for r in runs), "",
        "Bits count log2(codes) per keyframe token (FSQ levels of the tiny preset), not the positions. The "
        "per-channel tokenizer carries d = 56 times the codes of the shared one at equal k; its keyframe "
        "encoder attends over k·d tokens, hence its cost per step.", "",
        f"Wall time {time.perf_counter() - started:.0f} s (1 torch thread, a shared and busy CPU: step times "
        "are indicative).",
    ]
    text = "\n".join(lines) + "\n"
    click.echo(text)
    write_result(out, text, seed=seed, data={"oracle": oracle_rows, "trained": runs})


if __name__ == "__main__":
    main()
