"""Training budget of every shipped checkpoint, read from what its training wrote; and whether a paper-size
preset would train on this CPU in a few hours, from a measured per-step time.

Part 1 reads every committed checkpoint (``models/*/checkpoints/*.pt``, ``models/*/weights/*.pt``) with
``torch.load(weights_only=True)`` (:func:`dyadbench.torch_files.load_tensors_only`, as the product does)
and reports, from its ``meta`` only:

- steps: ``meta.step`` (the last optimiser step: DualTalk, TIMAR), else ``meta.steps`` (StyGazeTalk),
  else the predictor's configured ``config.predictor.steps`` (SFMS); the selected step ``meta.best_step``
  where the training kept the best weights rather than the last;
- epochs: ``meta.epoch`` where recorded; otherwise the passes over the training windows the steps make,
  steps × batch / ``meta.train_windows`` (or ``meta.windows``, or DualTalk's ``meta.directions``);
- wall time: ``meta.train_seconds`` (timed around the optimisation loop), else the sum of the per-epoch
  ``seconds`` of ``meta.history`` (TIMAR: each entry times one epoch), else the last ``seconds`` of a
  per-step history (DualTalk: elapsed since the start). A field that is not there is reported as
  "not recorded", never estimated;
- machine: the recorded device, torch thread count (``meta.settings.threads``) and world size (no
  checkpoint records the CPU model);
- command: ``meta.command`` where recorded.

Part 2 (skipped with ``--no-measure``) times the paper-size presets of StyGazeTalk (``base-se64`` style
encoder, ``base-se64-vel`` generator) and SFMS (``paper`` tokenizer and predictor) with the trainers a user
runs, each twice: at ``a`` and ``b`` steps (``--measure-steps a,b``). The marginal time per step,
(t_b − t_a) / (b − a) from the recorded ``train_seconds``, removes the fixed costs both runs share (the final
validation, the residual pool); times the preset's step count, it gives the single-threaded training time.

    python benchmarks/bench_training_budget.py                   # both parts
    python benchmarks/bench_training_budget.py --no-measure      # the checkpoint table only
    python benchmarks/bench_training_budget.py --measured-from benchmarks/results/training_budget.json
        # the checkpoint table re-read, part 2 taken from an earlier run's result file (not re-measured)
Writes benchmarks/results/training_budget.{json,md}.
"""

from __future__ import annotations

import json
import re
import sys
import tempfile
from pathlib import Path

import click
import torch

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from output import write_result  # noqa: E402  (benchmarks/output.py)
from timing import timed  # noqa: E402
from dyadbench.errors import InputError  # noqa: E402
from dyadbench.torch_files import load_tensors_only  # noqa: E402

NOT_RECORDED = "not recorded"
CHECKPOINT_GLOBS = ("models/*/checkpoints/*.pt", "models/*/weights/*.pt")
#: a training that fits "a few hours" on this CPU, single-threaded
FEW_HOURS = 4.0
#: steps of the untimed first run of every stage (imports, dataset caches and lazy initialisation happen there)
WARM_UP_STEPS = 1


def shipped_checkpoints(root: Path = ROOT) -> list[Path]:
    """Every committed checkpoint file, sorted by path."""
    return sorted({p for pattern in CHECKPOINT_GLOBS for p in root.glob(pattern)})


def _get(d: dict, *keys):
    for key in keys:
        if not isinstance(d, dict) or key not in d:
            return None
        d = d[key]
    return d


def wall_seconds(meta: dict) -> tuple[float | None, str]:
    """Recorded training wall time and the field it came from ((None, "not recorded") if none)."""
    if isinstance(meta.get("train_seconds"), (int, float)):
        return float(meta["train_seconds"]), "meta.train_seconds"
    history = meta.get("history")
    if isinstance(history, list) and history and all(isinstance(h, dict) and "seconds" in h for h in history):
        if all("epoch" in h for h in history):
            return float(sum(h["seconds"] for h in history)), "sum of meta.history[*].seconds (per epoch)"
        if all("step" in h for h in history):
            return float(history[-1]["seconds"]), "meta.history[-1].seconds (elapsed)"
    return None, NOT_RECORDED


def _batch(config: dict, meta: dict) -> int | None:
    for value in (_get(meta, "settings", "batch_size"), config.get("batch_size"), config.get("batch"),
                  _get(config, "generator", "batch"), _get(config, "style_encoder", "batch"),
                  _get(config, "predictor", "batch")):
        if isinstance(value, int):
            return value
    return None


def budget_row(name: str, checkpoint: dict) -> dict:
    """The training budget recorded in one loaded checkpoint (a dict with ``meta`` and ``config``)."""
    if not isinstance(checkpoint, dict) or not isinstance(checkpoint.get("meta"), dict):
        raise InputError(name, "not a dyadbench checkpoint (no 'meta' dict)")
    meta, config = checkpoint["meta"], checkpoint.get("config") or {}
    steps = next((v for v in (meta.get("step"), meta.get("steps"), _get(config, "predictor", "steps"))
                  if isinstance(v, int)), None)
    batch = _batch(config, meta)
    windows, unit = next(((meta[k], k.replace("train_", "")) for k in ("train_windows", "windows", "directions")
                          if isinstance(meta.get(k), int)), (None, None))
    if isinstance(meta.get("epoch"), int):
        epochs = str(meta["epoch"])
    elif steps and batch and windows:
        epochs = f"≈ {steps * batch / windows:.1f} passes ({steps} × {batch} / {windows} {unit})"
    else:
        epochs = NOT_RECORDED
    seconds, source = wall_seconds(meta)
    device, threads = _get(meta, "settings", "device"), _get(meta, "settings", "threads")
    world = meta.get("world_size")
    machine = ", ".join(x for x in (f"device {device}" if device else None,
                                    f"{threads} torch threads" if threads is not None else None,
                                    f"world size {world}" if world is not None else None) if x) or NOT_RECORDED
    command = meta.get("command") or _get(meta, "settings", "command") or NOT_RECORDED
    notes = []
    if "tokenizer_sha256" in meta:
        notes.append(f"stage-1 tokenizer ({meta.get('tokenizer')}, sha256 {meta['tokenizer_sha256'][:12]}…): "
                     "its training time is not recorded in this file")
    if "style_encoder_digest" in meta and meta["style_encoder_digest"]:
        notes.append(f"style encoder sha256 {meta['style_encoder_digest'][:12]}… trained separately")
    return {"checkpoint": name, "model": meta.get("model", NOT_RECORDED), "steps": steps,
            "best_step": meta.get("best_step"), "batch": batch, "epochs": epochs, "wall_seconds": seconds,
            "wall_source": source, "machine": machine, "threads": threads, "command": command, "seed": meta.get("seed"),
            "notes": notes}


def read_budget(path: Path, root: Path = ROOT) -> dict:
    """:func:`budget_row` of the checkpoint file ``path`` (loaded tensors-only)."""
    name = str(path.relative_to(root)) if path.is_relative_to(root) else str(path)
    return budget_row(name, load_tensors_only(path, what="dyadbench checkpoint"))


# --- part 2: per-step time of the paper-size presets --------------------------------------------------

def _train_sgt_style(tmp: Path, steps: int, batch: int) -> None:
    from models.stygazetalk.cli import train_style_encoder

    train_style_encoder.main(["--config", "base-se64", "--steps", str(steps), "--batch-size", str(batch),
                              "--val-every", str(10 * steps), "--threads", "1",
                              "--export", str(tmp / f"sgt-style-{steps}.pt")], standalone_mode=False)


def _train_sgt_generator(tmp: Path, steps: int, batch: int) -> None:
    """Needs the style encoder of the same ``steps`` (trained just before)."""
    from models.stygazetalk.cli import train_generator

    train_generator.main(["--config", "base-se64-vel", "--steps", str(steps), "--batch-size", str(batch),
                          "--threads", "1", "--style-encoder", str(tmp / f"sgt-style-{steps}.pt"),
                          "--export", str(tmp / f"sgt-gen-{steps}.pt")], standalone_mode=False)


def _sfms_args(steps: int, batch: int, clips: int) -> list[str]:
    return ["--config", "paper", "--steps", str(steps), "--clips", str(clips), "--batch-size", str(batch),
            "--val-windows", "64", "--threads", "1"]


def _train_sfms_tokenizer(tmp: Path, steps: int, batch: int, clips: int) -> None:
    from models.sfms.cli import train_tokenizer

    train_tokenizer.main([*_sfms_args(steps, batch, clips), "--export", str(tmp / f"sfms-tok-{steps}.pt")],
                         standalone_mode=False)


def _train_sfms_predictor(tmp: Path, steps: int, batch: int, clips: int) -> None:
    """Needs the tokenizer of the same ``steps`` (trained just before)."""
    from models.sfms.cli import train_predictor

    train_predictor.main([*_sfms_args(steps, batch, clips), "--tokenizer", str(tmp / f"sfms-tok-{steps}.pt"),
                          "--export", str(tmp / f"sfms-pred-{steps}.pt")], standalone_mode=False)


def paper_stages(clips: int) -> dict[str, tuple[object, int, int]]:
    """Stage -> (trainer(tmp, steps, batch), preset steps, preset batch), in training order; read from the
    presets (StyGazeTalk's spec-size ``base`` presets, SFMS's ``paper`` presets)."""
    from models.sfms.config import predictor_preset, tokenizer_preset
    from models.stygazetalk.config import get_generator_config, get_style_config

    style, gen = get_style_config("base-se64"), get_generator_config("base-se64-vel")
    tok, pred = tokenizer_preset("paper"), predictor_preset("paper")
    return {"StyGazeTalk style encoder (base-se64)": (_train_sgt_style, style.steps, style.batch_pairs),
            "StyGazeTalk generator (base-se64-vel)": (_train_sgt_generator, gen.steps, gen.batch),
            "SFMS tokenizer (paper)": (lambda t, n, b: _train_sfms_tokenizer(t, n, b, clips), tok.steps, tok.batch),
            "SFMS predictor (paper)": (lambda t, n, b: _train_sfms_predictor(t, n, b, clips), pred.steps, pred.batch)}


def marginal_step_seconds(t_a: float, t_b: float, a: int, b: int) -> float:
    """(t_b − t_a) / (b − a): seconds per step without the costs both runs share."""
    if b <= a:
        raise ValueError(f"need a < b, got {a}, {b}")
    return (t_b - t_a) / (b - a)


def measure_paper_size(a: int, b: int, clips: int, sfms_batch: int) -> dict[str, dict]:
    """CPU seconds per step and projected single-threaded training hours of each paper-size stage.

    Each stage's trainer runs in this process at ``a`` and at ``b`` steps; its CPU time (this process, one
    thread) is measured around the call, so other jobs on the machine do not inflate it. StyGazeTalk runs at
    its preset batch; SFMS at ``sfms_batch`` (its preset's 256 needs ~13 GB), its per-step time scaled by
    preset batch / ``sfms_batch`` (the cost of a step taken as linear in the batch)."""
    torch.set_num_threads(1)
    stages = paper_stages(clips)
    cpu: dict[int, dict[str, float]] = {a: {}, b: {}}
    with tempfile.TemporaryDirectory(prefix="budget-") as tmp:
        for n in (WARM_UP_STEPS, a, b):  # the warm-up run takes the first call's imports and caches; not timed
            for stage, (train, _, batch) in stages.items():
                run_batch = sfms_batch if stage.startswith("SFMS") else batch
                _, _, seconds = timed(lambda: train(Path(tmp), n, run_batch))
                if n in cpu:
                    cpu[n][stage] = seconds
    out = {}
    for stage, (_, total_steps, batch) in stages.items():
        run_batch = sfms_batch if stage.startswith("SFMS") else batch
        per_step = marginal_step_seconds(cpu[a][stage], cpu[b][stage], a, b)
        scaled = per_step * batch / run_batch
        out[stage] = {"cpu_seconds_at_a": cpu[a][stage], "cpu_seconds_at_b": cpu[b][stage], "run_batch": run_batch,
                      "per_step_at_run_batch": per_step, "batch": batch, "per_step": scaled, "steps": total_steps,
                      "hours": scaled * total_steps / 3600}
    return out


def _hours(seconds: float | None) -> str:
    return NOT_RECORDED if seconds is None else f"{seconds:.0f} s ({seconds / 3600:.2f} h)"


def _minutes(seconds: float | None) -> str:
    return "of unrecorded length" if seconds is None else f"{seconds / 60:.1f} min"


def earlier_measurement(path: Path) -> tuple[dict, tuple[int, int], int, int, float | None]:
    """Part 2 of an earlier result file of this benchmark: (per-stage rows, (a, b), SFMS clips, SFMS batch,
    wall seconds of that measurement). Files written before the wall time was kept in the data give it in
    their markdown ("whole measurement X min wall"); None where neither has it."""
    try:
        record = json.loads(path.read_text())
        data = record["data"]
        measured, steps = data["paper_size"], data["measure_steps"]
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise click.BadParameter(f"{path}: not a result file of this benchmark ({exc})") from None
    if not measured:
        raise click.BadParameter(f"{path}: holds no paper-size measurement (it was written with --no-measure)")
    wall = data.get("measure_wall_s")
    if wall is None and (m := re.search(r"whole measurement ([0-9.]+) min wall", record.get("markdown", ""))):
        wall = float(m.group(1)) * 60
    return measured, (steps[0], steps[1]), data["sfms_clips"], data["sfms_batch"], wall


def _markdown(rows: list[dict], measured: dict | None, a: int, b: int, clips: int, measure_wall: float | None,
              source: Path | None = None) -> str:
    lines = ["# Training budget of the shipped checkpoints", "",
             "Read from each committed checkpoint's `meta` (tensors-only load, as the product loads them); the "
             "fields used are listed in `benchmarks/bench_training_budget.py`. \"not recorded\" means the training "
             "did not write it; nothing here is estimated.", "",
             "| checkpoint | model | steps (selected) | epochs | wall time | from | machine | seed | command |",
             "|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        steps = NOT_RECORDED if r["steps"] is None else str(r["steps"])
        if r["best_step"] is not None:
            steps += f" ({r['best_step']})"
        command = r["command"] if r["command"] == NOT_RECORDED else f"`{r['command']}`"
        lines.append(f"| {r['checkpoint']} | {r['model']} | {steps} | {r['epochs']} | {_hours(r['wall_seconds'])} | "
                     f"{r['wall_source']} | {r['machine']} | {r['seed']} | {command} |")
    notes = [f"- {r['checkpoint']}: {n}" for r in rows for n in r["notes"]]
    if notes:
        lines += ["", "Notes:", *notes]
    known = sum(r["wall_seconds"] for r in rows if r["wall_seconds"] is not None)
    lines += ["", f"Recorded training wall time over the {len(rows)} checkpoints: {known / 3600:.2f} h "
                  f"({sum(r['wall_seconds'] is None for r in rows)} without a record). "
                  f"{sum(r['threads'] is not None for r in rows)} of them record the torch thread count and none the "
                  "CPU model; a wall time includes whatever else ran on the machine then."]
    if measured is not None:
        lines += ["", "## Paper-size presets on this CPU (single thread)", "",
                  f"Each stage trained with the user's trainer once untimed at {WARM_UP_STEPS} step (imports and "
                  f"caches), then at {a} and at {b} steps (SFMS on {clips} clips; "
                  "the per-step cost does not depend on the clip count), in one process with one torch thread; "
                  f"per step = (t_b − t_a) / ({b} − {a}) with t the process CPU time of the trainer call (data loading "
                  "and the final validation cancel out); SFMS ran at a smaller batch than its preset's "
                  "(the preset's batch 256 needed ~13 GB of this shared 23 GB machine) and its per-step time is "
                  "scaled linearly to the preset batch; projected = per step × the preset's steps. "
                  f"CPU time, not wall time: other jobs on the shared machine do not inflate it (whole measurement "
                  f"{_minutes(measure_wall)} wall). \"Few hours\" here means ≤ {FEW_HOURS:g} h."
                  + (f" Taken from the earlier measurement in `{source}` (not re-measured in this run)." if source
                     else ""), "",
                  f"| stage | run batch | CPU s at {a} steps | CPU s at {b} steps | s / step at run batch | preset batch | "
                  "s / step at preset batch | preset steps | projected | trainable in a few hours? |",
                  "|---|---|---|---|---|---|---|---|---|---|"]
        for stage, m in measured.items():
            verdict = "yes" if m["hours"] <= FEW_HOURS else "no"
            lines.append(f"| {stage} | {m['run_batch']} | {m['cpu_seconds_at_a']:.1f} s | {m['cpu_seconds_at_b']:.1f} s | "
                         f"{m['per_step_at_run_batch']:.3f} | {m['batch']} | {m['per_step']:.3f} | {m['steps']} | "
                         f"{m['hours']:.1f} h | {verdict} |")
        for model in ("StyGazeTalk", "SFMS"):
            total = sum(m["hours"] for s, m in measured.items() if s.startswith(model))
            lines.append(f"\n{model}, both stages: {total:.1f} h single-threaded "
                         f"({'within' if total <= FEW_HOURS else 'beyond'} a few hours).")
    return "\n".join(lines) + "\n"


@click.command()
@click.option("--measure/--no-measure", default=True, show_default=True,
              help="Also time the paper-size presets (minutes).")
@click.option("--measure-steps", default="5,15", show_default=True, metavar="A,B",
              help="The two step counts of the per-step measurement.")
@click.option("--clips", type=click.IntRange(min=2), default=16, show_default=True,
              help="SFMS clips for the per-step measurement.")
@click.option("--sfms-batch", type=click.IntRange(min=1), default=32, show_default=True,
              help="SFMS batch of the per-step measurement (scaled to the preset's batch).")
@click.option("--measured-from", type=click.Path(dir_okay=False, exists=True, path_type=Path), default=None,
              help="Take part 2 from this earlier result file of this benchmark (its .json) instead of measuring "
                   "again; the table then names that file.")
@click.option("--out", type=click.Path(dir_okay=False, path_type=Path),
              default=Path(__file__).parent / "results" / "training_budget.md", show_default=True)
def main(measure: bool, measure_steps: str, clips: int, sfms_batch: int, measured_from: Path | None,
         out: Path) -> None:
    """Write the training budget table of every shipped checkpoint (and the paper-size per-step times)."""
    try:
        a, b = (int(x) for x in measure_steps.split(","))
    except ValueError:
        raise click.BadParameter(f"--measure-steps must be two integers A,B, got {measure_steps!r}") from None
    rows = [read_budget(p) for p in shipped_checkpoints()]
    measured, wall, source = None, None, None
    if measured_from is not None:
        measured, (a, b), clips, sfms_batch, wall = earlier_measurement(measured_from)
        resolved = measured_from.resolve()
        source = resolved.relative_to(ROOT) if resolved.is_relative_to(ROOT) else measured_from
    elif measure:
        measured, wall, _ = timed(lambda: measure_paper_size(a, b, clips, sfms_batch))
    text = _markdown(rows, measured, a, b, clips, wall, source)
    click.echo(text)
    kept = measured is not None
    data = {"checkpoints": rows, "paper_size": measured, "measure_steps": [a, b] if kept else None,
            "sfms_clips": clips if kept else None, "sfms_batch": sfms_batch if kept else None,
            "measure_wall_s": wall if kept else None, "measured_from": str(source) if source else None}
    write_result(out, text, seed=0 if measure else None, data=data)


if __name__ == "__main__":
    main()
