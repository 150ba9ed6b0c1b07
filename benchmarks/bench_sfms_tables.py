"""SFMS Tables III–IV redone with seeds, validation-only selection and listening frames (issue #26).

Arms, all tiny tokenizers trained by the same loop (:func:`models.sfms.train_tokenizer.fit_tokenizer`: same
steps, batch, learning rates; seed s gives every arm the same training windows):

- ``static``: k keyframes at i·⌊T/k⌋;  ``dynamic``: Algorithm 1 and top-k as published (suppression radius 0);
- ``dynamic per-channel``: Algorithm 1 per channel (``mask_sharing = "channel"``), k keyframes in each of the d channels;
- ``dense FSQ``: every frame a keyframe (SFMS architecture, k = T);
- ``dense VQ-VAE``: the Learning2Listen-style grouped tokenizer (:class:`models.sfms.dense_vq.DenseVQVAE`, one VQ
  code per ``--downsample`` frames).

Two budgets. *Equal codebook*: every arm has ``--levels`` FSQ codes (the VQ-VAE a VQ codebook of the same size).
*Equal bits*: each k's bit budget B is that of the dynamic arm (k codes + one learned position set); static gets
the FSQ level set of the FSQ paper whose log2 size is nearest B/k, dense FSQ one level of L = round(2^(B/T))
codes, the VQ-VAE round(2^(B/tokens)) codes. Bits per window, one formula for every arm
(:func:`models.sfms.ablation.window_bits`): tokens·log2(codes) + (learned position sets)·log2 C(T, k).
Per-channel allocation cannot be brought to these budgets (at 2 codes and k = 1 it already carries
d·(1 + log2 T) bits), so it appears only at equal codebook size.

Selection: the weights with the lowest whole-window MSE on validation windows (the corpus's val split) are kept;
the test split is only scored. Scoring: test windows of each agent, MSE over its listening frames (agent silent,
partner speaking: the listening-head task; primary) and over whole windows (secondary), mean ± standard error
over seeds.

    python benchmarks/bench_sfms_tables.py --jobs 2          # writes benchmarks/results/sfms_tables_seeds.{md,json}
    python benchmarks/bench_sfms_tables.py --ks 3 --seeds 0 --steps 20 --out /tmp/t   # quick look
"""

from __future__ import annotations

import hashlib
import json
import math
import multiprocessing
import os
import platform
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import asdict, dataclass
from functools import partial
from pathlib import Path

import click
import numpy as np
import torch

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_sfms_keyframes import equal_bits_arm  # noqa: E402
from output import write_cache_entry, write_result  # noqa: E402  (benchmarks/output.py)
from seed_stats import mean_se  # noqa: E402  (benchmarks/seed_stats.py)
from dyadbench.registry import DATASETS  # noqa: E402
from models.sfms.ablation import (agent_motions_and_masks, code_usage, frame_errors, masked_windows,  # noqa: E402
                                  mse_by_cut, window_bits)
from models.sfms.config import to_dict, tokenizer_preset  # noqa: E402
from models.sfms.data import clip_motions, motion_stats  # noqa: E402
from models.sfms.dense_vq import DenseVQVAE  # noqa: E402
from models.sfms.distributed import World  # noqa: E402
from models.sfms.train_tokenizer import fit_tokenizer  # noqa: E402

RESULT = Path(__file__).parent / "results" / "sfms_tables_seeds.md"
WINDOW = 48
# FSQ level sets recommended by Mentzer et al. (Table 1) for 2^8 … 2^16 codes
FSQ_SETS = {8: (8, 6, 5), 10: (8, 5, 5, 5), 12: (7, 5, 5, 5, 5), 14: (8, 8, 8, 6, 5), 16: (8, 8, 8, 5, 5, 5)}


@dataclass(frozen=True)
class Arm:
    """One trained configuration: ``kind`` static | dynamic | channel | dense-fsq | dense-vq, keyframes k per
    window (per channel for ``channel``; T for dense FSQ), FSQ ``levels`` or a VQ codebook of ``vq_codes``,
    ``downsample`` frames per token of the VQ-VAE."""

    kind: str
    k: int
    levels: tuple[int, ...] = ()
    vq_codes: int = 0
    downsample: int = 1

    @property
    def label(self) -> str:
        return {"static": "static", "dynamic": "dynamic (Alg. 1)", "channel": "dynamic per-channel",
                "dense-fsq": "dense FSQ", "dense-vq": f"dense VQ-VAE (/{self.downsample})"}[self.kind]

    @property
    def n_codes(self) -> int:
        return self.vq_codes or math.prod(self.levels)

    def tokens(self, dim: int) -> int:
        return {"channel": self.k * dim, "dense-vq": WINDOW // self.downsample}.get(self.kind, self.k)

    def position_sets(self, dim: int) -> int:
        return {"dynamic": 1, "channel": dim}.get(self.kind, 0)

    def bits(self, dim: int) -> float:
        return window_bits(self.tokens(dim), self.n_codes, self.position_sets(dim), WINDOW, self.k)

    def config(self, common: dict):
        mode = {"static": "static", "dynamic": "dynamic", "channel": "dynamic"}.get(self.kind, "dense")
        quantiser = dict(quantizer="vq", vq_codes=self.vq_codes) if self.vq_codes else dict(fsq_levels=self.levels)
        return tokenizer_preset("tiny", keyframe_mode=mode, keyframes=min(max(self.k, 1), WINDOW),
                                suppression_radius=0, mask_sharing="channel" if self.kind == "channel" else "frame",
                                **quantiser, **common)

    def factory(self):
        return partial(DenseVQVAE, downsample=self.downsample) if self.kind == "dense-vq" else None


def equal_codebook_arms(ks: list[int], channel_ks: list[int], levels: tuple[int, ...], downsample: int) -> list[Arm]:
    """Static and dynamic arms at every k, per-channel at ``channel_ks``, dense FSQ and the VQ-VAE: ``levels`` codes."""
    codes = math.prod(levels)
    arms = [Arm(kind, k, levels) for k in ks for kind in ("static", "dynamic")]
    arms += [Arm("channel", k, levels) for k in channel_ks]
    return arms + [Arm("dense-fsq", WINDOW, levels), Arm("dense-vq", 0, vq_codes=codes, downsample=downsample)]


def equal_bits_arms(k: int, levels: tuple[int, ...], downsample: int, dim: int) -> dict[str, Arm]:
    """The arms at the bits of dynamic k (``levels`` codes): static, dense FSQ and dense VQ-VAE."""
    budget = Arm("dynamic", k, levels).bits(dim)
    per_token = min(FSQ_SETS, key=lambda b: abs(math.log2(math.prod(FSQ_SETS[b])) - budget / k))
    dense_levels = equal_bits_arm(k, math.prod(levels), WINDOW)[3]
    vq_codes = max(2, round(2.0 ** (budget / (WINDOW // downsample))))
    return {"static": Arm("static", k, FSQ_SETS[per_token]), "dense-fsq": Arm("dense-fsq", WINDOW, dense_levels),
            "dense-vq": Arm("dense-vq", 0, vq_codes=vq_codes, downsample=downsample)}


_DATA: dict | None = None  # loaded once per worker process by _load_once


def load_data(dataset: str, clips: int, val_windows: int, test_windows: int) -> dict:
    """Z-scored train motions (first ``clips`` train dialogues, both participants), validation windows and test
    windows with their listening masks; z-score statistics from the train motions."""
    open_split = DATASETS.load(dataset)
    train_src = open_split(None, "train")
    train_raw = clip_motions(train_src.load(i) for i in train_src.clip_ids()[:clips])
    mean, std = motion_stats(train_raw)
    out = {"train": [(a - mean) / std for a in train_raw], "mean": mean, "std": std}
    for split, limit in (("val", val_windows), ("test", test_windows)):
        src = open_split(None, split)
        motions, masks = agent_motions_and_masks((src.load(i) for i in src.clip_ids()), mean, std)
        out[split], out[split + "_masks"] = masked_windows(motions, masks, WINDOW, limit)
    return out


def _load_once(dataset: str, clips: int, val_windows: int, test_windows: int, threads: int) -> None:
    global _DATA
    torch.set_num_threads(threads)
    _DATA = load_data(dataset, clips, val_windows, test_windows)


def used_codes(model, windows: np.ndarray) -> torch.Tensor:
    """Code indices the model gives the windows (keyframe codes only for SFMS tokenizers)."""
    with torch.no_grad():
        out = model.encode(torch.as_tensor(windows))
    if isinstance(out, tuple):
        codes = out[2]
        return codes[codes >= 0]
    return out


def run_arm(arm: Arm, common: dict, seed: int, device: str = "cpu") -> dict:
    """Train one arm with ``seed`` on ``device`` (selection on validation windows), score it on the test
    windows (on the CPU)."""
    d = _DATA
    cfg = arm.config(common)
    extra = {"model_factory": arm.factory()} if arm.factory() else {}
    t0, c0 = time.perf_counter(), time.process_time()
    model, history = fit_tokenizer(cfg, d["train"], d["val"], motion_mean=d["mean"], motion_std=d["std"],
                                   seed=seed, progress=False, world=World(0, 1, torch.device(device)), **extra)
    seconds, cpu_train = time.perf_counter() - t0, time.process_time() - c0
    scores = mse_by_cut(*frame_errors(model, d["test"]), d["test_masks"])
    dim = d["train"][0].shape[1]
    return {"arm": asdict(arm), "seed": seed, **scores, "bits": arm.bits(dim), "tokens": arm.tokens(dim),
            "codes": arm.n_codes, "code_usage": code_usage(used_codes(model, d["test"]), arm.n_codes),
            "params": sum(p.numel() for p in model.parameters()), "best_step": history["best_step"],
            "best_val_mse_z": history["best_val_mse_z"], "val_windows": len(d["val"]), "seconds": seconds,
            "cpu_seconds_train": cpu_train, "cpu_seconds": time.process_time() - c0, "device": device,
            "config": to_dict(cfg)}


def _cache_file(folder: Path, job: tuple[Arm, int], settings: dict) -> Path:
    """The cache file of one run: named by the arm, the seed and a digest of the shared settings."""
    arm, seed = job
    digest = hashlib.sha256(json.dumps(settings, sort_keys=True).encode()).hexdigest()[:10]
    levels = "x".join(map(str, arm.levels)) or "vq"
    return Path(folder) / f"{arm.kind}-k{arm.k}-{levels}-{arm.vq_codes}-d{arm.downsample}-s{seed}-{digest}.json"


def fmt(values: list[float], digits: int = 4) -> str:
    m, s = mean_se(values)
    return f"{m:.{digits}f} ± {s:.{digits}f}"


def summary_row(arm: Arm, runs: list[dict], reference: list[dict], budget: str) -> tuple[str, dict]:
    """Markdown row and JSON summary of one arm over its seeds; ratios to ``reference`` (dynamic, same k),
    paired by seed."""
    by_seed = {r["seed"]: r for r in reference}
    ratio = [r["listen_mse_z"] / by_seed[r["seed"]]["listen_mse_z"] for r in runs]
    r0 = runs[0]
    summary = {"arm": asdict(arm), "label": arm.label, "budget": budget, "seeds": [r["seed"] for r in runs],
               "bits": r0["bits"], "tokens": r0["tokens"], "codes": r0["codes"], "params": r0["params"]}
    for key in ("listen_mse_z", "mse_z", "listen_mse_raw", "mse_raw", "code_usage"):
        summary[key] = dict(zip(("mean", "se"), mean_se([r[key] for r in runs])))
    summary["listen_ratio_to_dynamic"] = dict(zip(("mean", "se"), mean_se(ratio)))
    k = "–" if arm.kind.startswith("dense") else str(arm.k)
    row = (f"| {arm.label} | {k} | {arm.n_codes} | {r0['tokens']} | {r0['bits']:.0f} | {r0['params'] / 1e3:.0f} k | "
           f"**{fmt([r['listen_mse_z'] for r in runs])}** | {fmt(ratio, 3)} | {fmt([r['mse_z'] for r in runs])} | "
           f"{fmt([r['code_usage'] for r in runs], 2)} | {np.mean([r['cpu_seconds'] for r in runs]):.0f} |")
    return row, summary


HEADER = ("| arm | k | codes | tokens / window | bits / window | params | listening MSE (z) | ratio to dynamic "
          "(listening, paired) | whole-window MSE (z) | codebook used | CPU s / run |\n"
          "|---|---|---|---|---|---|---|---|---|---|---|")


@click.command()
@click.option("--ks", default="3,7", show_default=True, help="Comma-separated keyframe counts k.")
@click.option("--channel-ks", default="3,7,10", show_default=True,
              help="Keyframe counts of the per-channel arm (its keyframe encoder attends over k·56 tokens: at k = 7 "
                   "a step costs about 10× a shared-mask step on the CPU; the committed k = 7 and 10 runs trained "
                   "with --device cuda).")
@click.option("--seeds", default="0,1,2", show_default=True, help="Comma-separated training seeds of every arm.")
@click.option("--steps", type=int, default=300, show_default=True, help="Training steps of every arm.")
@click.option("--batch", type=int, default=16, show_default=True, help="Windows per step of every arm.")
@click.option("--lr", type=float, default=2e-3, show_default=True, help="Peak learning rate (the scorer's is half).")
@click.option("--samples", type=click.IntRange(min=1), default=2, show_default=True,
              help="Gumbel samples S per window of the dynamic arms.")
@click.option("--levels", default="8,6,5", show_default=True, help="FSQ levels of the equal-codebook arms.")
@click.option("--downsample", type=int, default=8, show_default=True, help="Frames per token of the dense VQ-VAE.")
@click.option("--dataset", default="synthetic-v2", show_default=True, help="Registered dataset (train/val/test).")
@click.option("--clips", type=int, default=200, show_default=True, help="Train dialogues used (first N).")
@click.option("--val-windows", type=int, default=128, show_default=True, help="Validation windows for selection.")
@click.option("--test-windows", type=int, default=1024, show_default=True, help="Test windows scored.")
@click.option("--threads", type=int, default=1, show_default=True, help="torch CPU threads per run.")
@click.option("--jobs", type=click.IntRange(min=1), default=1, show_default=True, help="Runs in parallel processes.")
@click.option("--device", default="cpu", show_default=True,
              help="Torch device the runs train on (cpu, cuda); scoring stays on the CPU. Each run records its "
                   "device, and the table names the runs not trained on the CPU.")
@click.option("--out", type=click.Path(path_type=Path), default=RESULT, show_default=True, help="Result name.")
@click.option("--cache", type=click.Path(path_type=Path), default=None,
              help="Folder of finished runs (one JSON per arm, seed and settings): runs found there are not retrained.")
def main(ks, channel_ks, seeds, steps, batch, lr, samples, levels, downsample, dataset, clips, val_windows, test_windows,
         threads, jobs, device, out, cache) -> None:
    """Train every arm with every seed, print the tables, write the result files."""
    k_values, seed_values = [int(k) for k in ks.split(",")], [int(s) for s in seeds.split(",")]
    fsq = tuple(int(v) for v in levels.split(","))
    dim = 56
    common = dict(steps=steps, batch=batch, lr_main=lr, lr_scorer=lr / 2, gumbel_samples=samples,
                  val_every=max(steps // 4, 1), normalisation="zscore")  # load_data z-scores
    channel_k_values = [int(k) for k in channel_ks.split(",") if k]
    codebook_arms = equal_codebook_arms(k_values, channel_k_values, fsq, downsample)
    bits_arms = {k: equal_bits_arms(k, fsq, downsample, dim) for k in k_values}
    arms = list(dict.fromkeys(codebook_arms + [a for k in k_values for a in bits_arms[k].values()]))
    # seed by seed, the costly per-channel runs first in each, so the pool stays busy to the end
    jobs_list = [(arm, seed) for seed in seed_values for arm in sorted(arms, key=lambda a: a.kind != "channel")]
    runs: dict[Arm, list[dict]] = {arm: [] for arm in arms}
    settings = {**common, "dataset": dataset, "clips": clips, "val_windows": val_windows,
                "test_windows": test_windows}
    cached = {job: _cache_file(cache, job, settings) for job in jobs_list} if cache else {}
    context = multiprocessing.get_context("spawn" if device != "cpu" else None)  # CUDA cannot follow a fork
    with ProcessPoolExecutor(max_workers=jobs, initializer=_load_once, mp_context=context,
                             initargs=(dataset, clips, val_windows, test_windows, threads)) as pool:
        futures = [None if cached.get(job) and cached[job].exists() else
                   pool.submit(run_arm, job[0], common, job[1], device)
                   for job in jobs_list]
        for (arm, seed), future in zip(jobs_list, futures):
            r = json.loads(cached[arm, seed].read_text()) if future is None else future.result()
            if future is not None and cache:
                write_cache_entry(cached[arm, seed], r)
            runs[arm].append(r)
            click.echo(f"{arm.label:24s} k={arm.k:2d} codes={arm.n_codes:6d} seed {seed}: listening MSE z "
                       f"{r['listen_mse_z']:.4f}, whole {r['mse_z']:.4f}, best step {r['best_step']} "
                       f"({r['seconds']:.0f} s, CPU {r['cpu_seconds']:.0f} s)", err=True)
    first = next(iter(runs.values()))[0]
    summaries, codebook_rows, bits_rows = [], [], []
    for arm in codebook_arms:
        same_k = arm.kind in ("static", "dynamic", "channel") and arm.k in k_values
        ref = runs[Arm("dynamic", arm.k if same_k else k_values[-1], fsq)]
        row, s = summary_row(arm, runs[arm], ref, "equal codebook")
        codebook_rows.append(row)
        summaries.append(s)
    for k in k_values:
        ref = runs[Arm("dynamic", k, fsq)]
        for arm in [Arm("dynamic", k, fsq), *bits_arms[k].values()]:
            row, s = summary_row(arm, runs[arm], ref, f"bits of dynamic k = {k}")
            bits_rows.append(row.replace(f"| {arm.label} |", f"| {arm.label} [B({k})] |", 1))
            summaries.append(s)
    n_runs = sum(len(v) for v in runs.values())
    cpu = sum(r["cpu_seconds"] for v in runs.values() for r in v)
    run_wall = sum(r["seconds"] for v in runs.values() for r in v)
    lines = [
        "# SFMS Tables III–IV with seeds: static vs dynamic vs per-channel vs dense (listening frames)",
        "",
        f"Command: `python benchmarks/bench_sfms_tables.py --ks {ks} --channel-ks {channel_ks} --seeds {seeds} --steps {steps} --batch {batch} "
        f"--lr {lr:g} --samples {samples} --levels {levels} --downsample {downsample} --dataset {dataset} "
        f"--clips {clips} --val-windows {val_windows} --test-windows {test_windows} --jobs {jobs}`",
        "",
        f"**Short training budgets**: every run is a tiny tokenizer (width 64, one layer per stack) trained "
        f"{steps} steps × batch {batch} (peak lr {lr:g}, scorer {lr / 2:g}, S = {samples} Gumbel samples for the "
        f"dynamic arms) on the first {clips} {dataset} train dialogues (both participants, z-scored with their "
        f"mean/std). The dense VQ-VAE (Learning2Listen style) maps each group of {downsample} frames linearly to "
        "one latent, runs one encoder layer, quantises it with a VQ codebook (nearest code, straight-through, "
        "codebook + commitment loss) and decodes with one layer and the transposed linear map. These figures compare early training under one fixed budget, not converged capacity, "
        "and nothing was tuned per arm.",
        "",
        f"Selection: every {common['val_every']} steps the whole-window MSE on {first['val_windows']} "
        "validation windows (non-overlapping 48-frame windows of every agent of the first val-split dialogues, "
        "in order) is measured in eval mode; the lowest is kept. The test split is only scored: "
        f"{first['frames'] // WINDOW} non-overlapping 48-frame windows (every agent of the first test dialogues, "
        f"in order), of whose {first['frames']} frames {first['listen_frames']} are *listening frames* (the agent silent, "
        "its partner speaking, from the clips' speaking masks: the listening-head task, primary cut). MSE is "
        "over frames and the 56 dims in z-space (train mean/std); mean ± standard error over seeds "
        f"{seeds} (sample std / √n). *Ratio to dynamic* is arm / dynamic listening MSE per seed (same k, same "
        "training windows), then mean ± s.e.; > 1: dynamic (Algorithm 1) reconstructs better. Bits per window "
        "= tokens × log2(codes) + learned position sets × log2 C(48, k) (1 set for dynamic, 56 for per-channel, "
        "0 for static and dense). *Codebook used*: the fraction of codes that occur in the test windows' tokens.",
        "",
        f"## Equal codebook size ({math.prod(fsq)} codes: FSQ [{levels}], the VQ-VAE a {math.prod(fsq)}-entry VQ "
        f"codebook; the ratio of rows without a dynamic arm of their k (dense{other_k_note(channel_k_values, k_values)}) "
        f"is to dynamic k = {k_values[-1]})",
        "",
        HEADER,
        *codebook_rows,
        "",
        "## Equal bits per window (B(k) = bits of dynamic k; static: the FSQ-paper level set nearest B/k bits "
        "per token; dense FSQ: one level of L codes per frame; VQ-VAE: round(2^(B/tokens)) codes)",
        "",
        HEADER,
        *bits_rows,
        "",
        f"Per-channel allocation is not in the equal-bits table: at k = 1 and 2 codes it carries "
        f"{window_bits(dim, 2, dim, WINDOW, 1):.0f} bits, above every B(k) here.",
        "",
        f"Compute: {cpu / 60:.1f} CPU minutes of training and scoring over {n_runs} runs ({run_wall / 60:.0f} minutes "
        f"of run wall time summed: the CPU was shared with other work) on {platform.machine()}, {threads} torch "
        f"thread per run, {os.cpu_count()} CPUs visible.{off_cpu_note(runs)}",
        "",
        "Paper (L2L, MSE ×10⁻²): Table III dynamic 0.15 / 0.13 / 0.12 at k = 3 / 7 / 10, static 0.89 / 0.64 / "
        "0.33, VQ-only (dense) 0.26; Table IV L2L VQ-256 1.44, Dense-FSQ FQ-1024 0.73, Sparse-VQ 0.05, "
        "Sparse-FSQ 0.03. The paper states neither its bits nor its seeds.",
    ]
    text = "\n".join(lines) + "\n"
    click.echo(text)
    write_result(out, text, seed=seed_values, argv=_without_cache(sys.argv),
                 data={"summaries": summaries, "runs": [r for v in runs.values() for r in v],
                       "dataset": dataset, "cpu_seconds": cpu, "run_wall_seconds": run_wall})


def other_k_note(channel_ks: list[int], ks: list[int]) -> str:
    """", per-channel k = …" for the per-channel keyframe counts with no dynamic arm of the same k, or ""."""
    other = [str(k) for k in channel_ks if k not in ks]
    return f", per-channel k = {', '.join(other)}" if other else ""


def off_cpu_note(runs: dict[Arm, list[dict]]) -> str:
    """A sentence naming the runs trained on another device than the CPU (runs recorded before runs kept their
    device trained on the CPU), or ""."""
    moved: dict[str, list[str]] = {}
    for arm, arm_runs in runs.items():
        for r in arm_runs:
            if r.get("device", "cpu") != "cpu":
                moved.setdefault(r["device"], []).append(f"{arm.label} k = {arm.k} seed {r['seed']}")
    return "".join(f" Trained on {dev} (the rest on the CPU; their CPU s / run is the host process's time, not the "
                   f"training's): {', '.join(names)}." for dev, names in moved.items())


def _without_cache(argv: list[str]) -> list[str]:
    """The command line to record: ``--cache DIR`` only skips finished runs, it does not change the result."""
    out, skip = [], False
    for arg in argv:
        if skip or arg == "--cache" or arg.startswith("--cache="):
            skip = arg == "--cache"
            continue
        out.append(arg)
    return out


if __name__ == "__main__":
    main()
