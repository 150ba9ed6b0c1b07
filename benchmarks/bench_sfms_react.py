"""SFMS on REACT (the paper's Table II line): the shipped REACT variant against REACT's trivial baselines.

    python benchmarks/bench_sfms_react.py     # --clips 100 --splits val test; ~10 CPU min on 2 cores

For each split (val, test) of the embedded corpus written in the REACT layout (``--clips`` dialogues,
N = 2·clips mirrored samples, seed 0; the train split at its default 200 dialogues feeds MeanSeq and
MeanFr; all generated into ``--data`` unless present), it

1. generates R = 10 reactions of 750 frames per sample with ``models/sfms/checkpoints/sfms-tiny-react.pt``
   (``python -m models.sfms.react``, seed 0) and the official trivial baselines GT, Random, Mime, MeanSeq,
   MeanFr (``python -m baselines.react NAME``) into ``out/react-preds/<split>/<model>.npz``;
2. scores each with ``dyadbench score PRED --suite react --gt DATA --split SPLIT --model NAME --out
   out/react-scores/<split>/<model>`` (GT with ``--oracle``) and copies its ``result.json`` to
   ``results/react-synth/<split>/<model>.json`` (the leaderboard's rows, ``leaderboards/react_wide.csv``);
3. prints the table beside the paper's Table II and writes ``benchmarks/results/sfms_react.{json,md}``.

Then regenerate the tables: ``dyadbench leaderboard results/ --latex --table1 --out leaderboards/`` and
``dyadbench report results --benchmarks benchmarks/results --out RESULTS.md``.
"""

from __future__ import annotations

import os
import resource
import shutil
import subprocess
import sys
from pathlib import Path

import click
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from output import Transcript, write_result  # noqa: E402  (benchmarks/output.py)
from baselines import react as react_baselines  # noqa: E402
from dyadbench.datasets.react import ReactSplit  # noqa: E402
from dyadbench.metrics.react import FRAMES  # noqa: E402
from dyadbench.results import load_result  # noqa: E402
from dyadbench.synth.react_writer import SPLIT_SIZES, write_react_split  # noqa: E402

RESULT = Path(__file__).parent / "results" / "sfms_react"
COLUMNS = ("FRCorr", "FRDist", "FRDiv", "FRVar", "FRDvs", "FRSyn")
MODELS = ("sfms", *react_baselines.NAMES)
#: The paper's Table II (REACT test set; FRRea left out: not computed here). MeanSeq has no row there.
PAPER = {"gt": (0.85, 0.00, 0.0000, 0.0724, 0.2483, 47.69), "random": (0.05, 237.23, 0.1667, 0.0833, 0.1667, 44.10),
         "mime": (0.38, 92.94, 0.0000, 0.0724, 0.2483, 38.54), "mean-fr": (0.00, 97.86, 0.0, 0.0, 0.0, 49.00),
         "Dense-FSQ": (0.31, 84.93, 0.1164, 0.0348, 0.1166, 47.42),
         "sfms": (0.84, 66.89, 0.1207, 0.0871, 0.1212, 45.66)}


def ensure_split(data: Path, split: str, clips: int | None) -> None:
    """Write ``split`` of the embedded corpus in the REACT layout into ``data`` unless it holds that many dialogues."""
    want = clips or SPLIT_SIZES[split]
    csv = data / f"{split}.csv"
    if csv.is_file() and len(ReactSplit.open(data, split).pairs) == want:
        return
    write_react_split(data, split=split, clips=want, seed=0, progress=False, force=True)


def predict(name: str, data: Path, split: str, weights: Path) -> Path:
    """Write ``name``'s predictions for ``split`` with its documented command (seed 0); returns the .npz."""
    pred = ROOT / "out" / "react-preds" / split / f"{name}.npz"
    common = ["--data", shown(data), "--split", split, "--seed", "0", "--out", shown(pred)]
    if name == "sfms":
        command = ["-m", "models.sfms.react", "--weights", shown(weights), "--threads", "1", *common]
    else:
        command = ["-m", "baselines.react", name, *common]
    subprocess.run([sys.executable, *command], check=True, cwd=ROOT, stdout=subprocess.DEVNULL)
    return pred


def shown(path: Path) -> str:
    """``path`` relative to the repository when inside it (results record the paths as given)."""
    path = Path(path).resolve()
    return str(path.relative_to(ROOT)) if path.is_relative_to(ROOT) else str(path)


def child_cpu() -> float:
    """CPU seconds (user + system) of the finished child processes so far."""
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def score(pred: Path, name: str, data: Path, split: str, jobs: int) -> Path:
    """``dyadbench score`` of one prediction file; its result.json copied to results/react-synth/<split>/<name>.json."""
    out = ROOT / "out" / "react-scores" / split / name
    command = [sys.executable, "-m", "dyadbench", "score", shown(pred), "--suite", "react", "--gt", shown(data),
               "--split", split, "--model", name, "--out", shown(out), "-j", str(jobs)]
    if name in react_baselines.ORACLES:
        command.append("--oracle")
    shutil.rmtree(out, ignore_errors=True)
    subprocess.run(command, check=True, cwd=ROOT, stdout=subprocess.DEVNULL)
    target = ROOT / "results" / "react-synth" / split / f"{name}.json"
    target.parent.mkdir(parents=True, exist_ok=True)
    staged = target.with_name(f".{target.name}.tmp")
    shutil.copyfile(out / "result.json", staged)
    os.replace(staged, target)  # the result file appears whole or not at all
    return target


def per_sample(result, key: str) -> dict[str, float]:
    """Sample (speaker path) -> the per-sample value of ``key`` in a result's per-clip rows."""
    return {row["clip"]: float(row[key]) for row in result.per_clip}


def paired(results: dict, keys=("FRCorr", "FRDist")) -> list[str]:
    """SFMS minus each non-oracle baseline, sample by sample: mean ± s.e. (std(d, ddof=1)/√n) and how many
    samples SFMS scores lower."""
    lines = ["| sfms − model | " + " | ".join(keys) + " |", "|---" * (len(keys) + 1) + "|"]
    for name, result in results.items():
        if name == "sfms" or result.model.oracle:
            continue
        cells = []
        for key in keys:
            a, b = per_sample(results["sfms"], key), per_sample(result, key)
            d = np.array([a[k] - b[k] for k in a])
            se = d.std(ddof=1) / np.sqrt(len(d))
            cells.append(f"{d.mean():+.4g} ± {se:.2g} ({int((d < 0).sum())} of {len(d)} lower)")
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
    return lines


def checkpoint_facts(weights: Path) -> list[str]:
    """What the shipped checkpoint records: size, parameters, training data, steps, time, validation CE."""
    from dyadbench.training.checkpoint import file_digest  # noqa: PLC0415
    from models.sfms.react import load_react_sfms  # noqa: PLC0415

    model, meta = load_react_sfms(weights)
    params = [sum(p.numel() for p in part.parameters()) for part in (model.tokenizer, model.predictor)]
    last = meta["val"][-1]
    data = meta["data"]
    return [f"## Checkpoint `{weights.relative_to(ROOT) if weights.is_relative_to(ROOT) else weights}`", "",
            f"- {weights.stat().st_size / 1e6:.2f} MB, sha256 {file_digest(weights)[:16]}…; parameters: tokenizer "
            f"{params[0]:,}, predictor {params[1]:,} (preset {meta['preset']}, seed {meta['seed']})",
            f"- trained on {data['dataset']}/{data['split']} at {data['root']} (layout {data['layout']}): "
            f"{data['clips_used'] - len(data['val_clips'])} dialogues, {len(data['val_clips'])} held out for "
            "validation",
            f"- predictor: {last['step']} steps, {meta['train_seconds']:.0f} s (as recorded by the training run); best "
            f"validation weighted CE {meta['best_val_ce']:.3f} at step {meta['best_step']}, against "
            f"{last['unigram_ce']:.3f} for the train class frequencies (unigram predictor)"]


def row(label: str, values) -> str:
    return f"| {label} | " + " | ".join(f"{v:.4f}" if abs(v) < 10 else f"{v:.2f}" for v in values) + " |"


@click.command()
@click.option("--data", type=click.Path(file_okay=False, path_type=Path), default=ROOT / "out" / "react-synth",
              show_default=True, help="REACT root (generated here when a split is missing or of another size).")
@click.option("--clips", type=click.IntRange(min=2), default=100, show_default=True,
              help="Dialogues of each scored split (N = 2·clips samples).")
@click.option("--splits", multiple=True, type=click.Choice(["val", "test"]), default=("val", "test"),
              show_default=True)
@click.option("--weights", type=click.Path(dir_okay=False, path_type=Path),
              default=ROOT / "models" / "sfms" / "checkpoints" / "sfms-tiny-react.pt", show_default=True)
@click.option("--jobs", "-j", type=click.IntRange(min=1), default=2, show_default=True, help="Scoring threads.")
def main(data: Path, clips: int, splits: tuple[str, ...], weights: Path, jobs: int) -> None:
    log = Transcript()
    ensure_split(data, "train", None)
    tables, numbers = [], {}
    for split in splits:
        ensure_split(data, split, clips)
        lines = [f"## {split}: {2 * clips} samples ({clips} dialogues) × 10 reactions × {FRAMES} frames",
                 "", "| model | " + " | ".join(COLUMNS) + " | generate CPU s | score CPU s |",
                 "|---" * (len(COLUMNS) + 3) + "|"]
        numbers[split], results = {}, {}
        for name in MODELS:
            cpu = child_cpu()
            pred = predict(name, data, split, weights)
            made = child_cpu() - cpu
            cpu = child_cpu()
            result = results[name] = load_result(score(pred, name, data, split, jobs))
            scored = child_cpu() - cpu
            values = [result.metrics[c] for c in COLUMNS]
            numbers[split][name] = {**dict(zip(COLUMNS, values)), "generate_cpu_s": made, "score_cpu_s": scored}
            lines.append(row(name + (" (oracle)" if result.model.oracle else ""), values)
                         + f" {made:.0f} | {scored:.0f} |")
            log.say(lines[-1])
        pairs = paired(results)
        lines += ["", f"Paired over the {split} samples (FRCorr: higher is better; FRDist: lower is better):", "",
                  *pairs]
        log.say("\n".join(pairs))
        tables.append("\n".join(lines))
    paper = ["## The paper's Table II (real REACT test set; FRRea left out)", "",
             "| model | " + " | ".join(COLUMNS) + " |", "|---" * (len(COLUMNS) + 1) + "|"]
    paper += [row(name, values) for name, values in PAPER.items()]
    text = ("# SFMS on REACT (embedded corpus in the REACT layout)\n\n"
            "FRCorr sums over the 10 reactions (official script; range about [-10, 10]); FRSyn is reaction 0's "
            "(official). generate / score CPU s = CPU seconds of the command that makes the predictions (`python -m "
            "models.sfms.react` / `python -m baselines.react NAME`) / of `dyadbench score` "
            f"(-j {jobs}).\n\n" + "\n".join(checkpoint_facts(weights)) + "\n\n" + "\n\n".join(tables)
            + "\n\n" + "\n".join(paper) + "\n")
    json_path, md_path = write_result(RESULT, text, seed=0, data=numbers)
    log.say(f"wrote {json_path} and {md_path}")


if __name__ == "__main__":
    main()
