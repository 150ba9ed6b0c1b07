"""``dyadbench sweep``: evaluate models over splits and context lengths, one result file per run.

Each run writes ``OUT/<dataset>/<split>/n<context>/<model>.json``, or ``<model>@<variant>.json`` when a
protocol setting differs from the default (e.g. ``timar@cfg2.json`` for ``--cfg-scale 2``; see
:func:`dyadbench.protocol.config.variant_label`; ``mime@partner-motion-drop0.3.json`` for ``--perturb
partner-motion:drop:0.3``, :func:`dyadbench.protocol.perturbations.variant_part`), so variants never overwrite
or skip each other. A run is
skipped (unless --force) when its file holds a valid result whose recorded configuration
(:mod:`dyadbench.protocol.run_configuration`: data and its content digest, --clips, settings, model
version and weights digest, train split) equals the requested one, so adding a model's rows never
re-runs the others; otherwise it is re-run and the reason printed. The model is built (baselines fitted,
from their cache) before that comparison, and nothing is streamed for a skipped run.
``dyadbench leaderboard OUT`` then rebuilds the tables from every file.

``sweep --stale --out OUT`` re-runs exactly the result files under OUT whose provenance no longer matches
the current code and data (:mod:`dyadbench.staleness`), each with the settings it records, and writes
the new result over the same file (atomically).
"""

from __future__ import annotations

import contextlib
from dataclasses import replace
from pathlib import Path
from typing import Callable, Iterator

import click
from click.core import ParameterSource

from dyadbench import distributed
from dyadbench.cli.cluster import ClusterSweep, scheduler_option
from dyadbench.cli.eval import (data_options, is_predictions_folder, predictions_at, protocol_options,
                                resolve_dataset, run_one, run_variant, save_result, summary, wav2vec_extra)
from dyadbench.cli.options import IntList, check_cfg_scale
from dyadbench.cli.splits import split_help, sweep_splits
from dyadbench.errors import ConfigError, InputError
from dyadbench.outputs import check_cache, check_folder, owned_folder
from dyadbench.protocol.config import ProtocolConfig
from dyadbench.protocol.run_configuration import differences
from dyadbench.registry import MODELS
from dyadbench.results import EvalResult, load_result, result_files
from dyadbench.staleness import STALE, Checker, RecordedRun, open_split, recorded_run

#: Options describing which runs to make; ``--stale`` takes them from each result file and refuses them.
RUN_OPTIONS = ("models", "splits", "context_list", "turn_seconds", "tail", "history_agent", "seed", "cfg_scale",
               "weights", "wav2vec", "device", "speech_norm", "perturb", "noise_scale", "data", "dataset", "train",
               "allow_train_overlap", "clips", "keep_predictions", "per_clip", "force")


def result_path(out: Path, dataset: str, split: str, context: int, model: str, variant: str = "") -> Path:
    """Where a sweep run's result file goes (``variant``: :func:`~dyadbench.protocol.config.variant_label`)."""
    return out / dataset / split / f"n{context}" / (f"{model}@{variant}.json" if variant else f"{model}.json")


def without_per_clip(result: EvalResult) -> EvalResult:
    """The result with per-clip metrics dropped and per-clip lists in ``coverage`` replaced by counts."""
    coverage = {k: len(v) if isinstance(v, (list, dict)) else v for k, v in result.coverage.items()}
    return replace(result, per_clip=[], coverage=coverage,
                   notes=result.notes + ["per-clip metrics not kept (--no-per-clip); coverage lists are counts"])


@contextlib.contextmanager
def kept_predictions(folder: Path | None, force: bool) -> Iterator[Path | None]:
    """Where a run writes its predictions: None (the runner's temporary folder, removed after scoring) or,
    with --keep-predictions, a temporary folder swapped onto ``folder`` when the run completes
    (:func:`dyadbench.outputs.owned_folder`)."""
    if folder is None:
        yield None
        return
    with owned_folder(folder, "predictions", force=force, label=f"--keep-predictions folder {folder}",
                      legacy=is_predictions_folder) as staging:
        yield staging


class Unchanged(Exception):
    """Raised before streaming when a stored result's configuration equals the requested one."""


def reuse_check(path: Path) -> Callable[[dict], None] | None:
    """What to do with an existing result file: None to re-run (the reason printed), or the check
    :func:`~dyadbench.protocol.runner.evaluate` runs before streaming, which raises :class:`Unchanged` when
    the recorded configuration equals the requested one and otherwise prints what differs."""
    try:
        recorded = load_result(path).configuration
    except InputError as exc:
        click.echo(f"re-running {path}: result file unreadable: {exc.problem}")
        return None
    if recorded is None:
        click.echo(f"re-running {path}: the result file records no configuration (an older dyadbench wrote it)")
        return None

    def check(requested: dict) -> None:
        if recorded == requested:
            raise Unchanged
        click.echo(f"re-running {path}: {'; '.join(differences(recorded, requested))}")
    return check


def rerun(run: RecordedRun, checker: Checker, jobs: int, threads: int | None, batch: int = 1) -> EvalResult:
    """Run a result file's :class:`~dyadbench.staleness.RecordedRun` again: its model (with the weights and
    train split it used), split, ``--clips`` (all clips when it ran them all), protocol settings and seed."""
    source = open_split(run.dataset, run.root, run.split)
    clips = None if run.clips is None or run.clips >= len(source) else run.clips
    return run_one(run.model, source, checker.train_split(run), run.config, cfg_scale=run.cfg_scale,
                   weights=checker.weights(run), clips=clips, jobs=jobs, predictions_dir=None, threads=threads,
                   batch=batch)


def rerun_stale(out: Path, jobs: int, threads: int | None, batch: int = 1) -> None:
    """``sweep --stale``: re-run every stale result file under ``out`` and write it over the file (kept
    without per-clip rows when it had none)."""
    checker = Checker(generate=True)
    files = result_files([out])
    rerun_count = 0
    for path in files:
        verdict = checker.check(path)
        if verdict.status != STALE:
            continue
        click.echo(f"re-running {verdict.line()}")
        run = recorded_run(load_result(path))
        result = rerun(run, checker, jobs, threads, batch)
        written(result, path, run.per_clip)
        rerun_count += 1
    click.echo(f"{rerun_count} stale result file(s) of {len(files)} under {out} re-run")


def _given(ctx: click.Context, names: tuple[str, ...]) -> list[str]:
    """The command-line spelling of the options among ``names`` that the user gave."""
    return [p.opts[0] for p in ctx.command.params if p.name in names
            and ctx.get_parameter_source(p.name) in (ParameterSource.COMMANDLINE, ParameterSource.ENVIRONMENT)]


def _csv(value: str, what: str) -> list[str]:
    items = [v.strip() for v in value.split(",") if v.strip()]
    if not items:
        raise ConfigError(f"--{what} needs at least one value")
    return items


@click.command()
@click.option("--models", default=None,
              help="Comma-separated registered models, e.g. zero,mean-frame,oracle (see `dyadbench models`). "
                   "Required unless --stale.")
@click.option("--splits", default=None,
              help=split_help("Comma-separated splits [default: test,ood; for a single split folder as --data, "
                              "that folder alone, under its name]."))
@click.option("--contexts", "context_list", default="0,3,7", show_default=True, type=IntList(min=0),
              help="Comma-separated history lengths n (each >= 0).")
@protocol_options
@data_options
@click.option("--out", "out", type=click.Path(file_okay=False, path_type=Path), default=Path("results"),
              show_default=True, help="Result folder: OUT/<dataset>/<split>/n<context>/<model>.json "
                   "(<model>@<variant>.json for non-default settings, e.g. timar@cfg2.json).")
@click.option("--keep-predictions", type=click.Path(file_okay=False, path_type=Path), default=None,
              help="Also keep the prediction files under DIR/<dataset>/<split>/n<context>/<model>/ "
                   "(default: written to a temporary folder and removed after scoring).")
@click.option("--per-clip/--no-per-clip", default=True, show_default=True,
              help="Keep per-clip metrics in each result file. --no-per-clip keeps the mean metrics only "
                   "(small files, e.g. results committed beside the leaderboards).")
@click.option("--force", is_flag=True, help="Re-run and overwrite runs whose result file exists.")
@click.option("--stale", is_flag=True,
              help="Re-run only the result files under --out whose provenance no longer matches the current "
                   "code and data (the rows `dyadbench leaderboard` warns about), each with the settings it "
                   "records, writing over the file. Takes only --out, --scheduler, --jobs, --threads and --batch.")
@click.pass_context
@scheduler_option
def sweep(ctx: click.Context, models: str | None, splits: str | None, context_list: list[int], turn_seconds: float,
          tail: str, history_agent: str, seed: int, cfg_scale: float, weights: Path | None,
          wav2vec: Path | None, device: str, speech_norm: str, perturb: tuple, noise_scale: float | None, data: Path | None,
          dataset: str | None, train: Path | None, allow_train_overlap: bool, clips: int | None, jobs: int,
          threads: int | None, batch: int, out: Path, keep_predictions: Path | None, per_clip: bool, force: bool,
          stale: bool) -> None:
    """Evaluate every MODEL x SPLIT x CONTEXT and write one result file per run.

    \b
    The committed leaderboards of the embedded corpus are regenerated by:
      dyadbench sweep --models zero,mean-frame,median-frame,random,mime,lagged-mirror,nn-retrieval,oracle \\
          --splits test,ood --contexts 0,3,7 --out results/ --no-per-clip --jobs 2
      dyadbench leaderboard results/ --out leaderboards/ --latex
    Rows whose provenance no longer matches (e.g. a model's new version) are re-run by:
      dyadbench sweep --stale --out results/ --jobs 2
    With --scheduler each run is one task on the cluster (--stale: each run's clips in chunks); a run that
    fails is reported after the others finish, and the same command again does only what is missing.
    """
    if stale:
        given = _given(ctx, RUN_OPTIONS)
        if given:
            raise ConfigError(f"--stale re-runs each stale file with the settings it records: "
                              f"{', '.join(given)} cannot be given with it")
        check_cache()
        check_folder(out, f"--out {out}")
        rerun_stale(out, jobs, threads, batch)
        return
    if models is None:
        raise ConfigError("--models is required (or --stale to re-run the stale result files under --out)")
    names = _csv(models, "models")
    for name in names:
        MODELS.get(name)
    check_cfg_scale(names, cfg_scale)
    dataset_name = resolve_dataset(data, dataset)
    check_cache()
    check_folder(out, f"--out {out}")
    if keep_predictions is not None:
        check_folder(keep_predictions, f"--keep-predictions {keep_predictions}")
    runs = sweep_splits(data, dataset_name, None if splits is None else _csv(splits, "splits"), train=train,
                        allow_overlap=allow_train_overlap)
    run_or_send = runs_to_files()
    for source, train_split in runs:
        split = source.split
        for context in context_list:
            config = ProtocolConfig(turn_seconds=turn_seconds, context=context, tail=tail,
                                    history_agent=history_agent, seed=seed, speech_norm=speech_norm,
                                    perturbations=perturb, noise_scale=noise_scale)
            variant = run_variant(config, cfg_scale)
            for name in names:
                path = result_path(out, dataset_name, split, context, name, variant)
                preds = (result_path(keep_predictions, dataset_name, split, context, name, variant).with_suffix("")
                         if keep_predictions else None)
                run_or_send(path, name, source, train_split, config, cfg_scale=cfg_scale, weights=weights,
                            clips=clips, jobs=jobs, threads=threads, extra=wav2vec_extra(wav2vec), force=force,
                            per_clip=per_clip, preds=preds, device=device, batch=batch)
    if isinstance(run_or_send, ClusterSweep):
        run_or_send.finish()


def run_to_file(path: Path, name: str, source, train_split, config: ProtocolConfig, *, cfg_scale: float,
                weights: Path | None, clips: int | None, jobs: int, threads: int | None, extra: dict, force: bool,
                per_clip: bool, preds: Path | None = None, device: str = "cpu", batch: int = 1) -> EvalResult | None:
    """One sweep run written to ``path``; skipped (None returned) when ``path`` holds a result of the same
    configuration and not ``force``; ``preds``: where to keep the predictions (None: not kept)."""
    check = reuse_check(path) if path.exists() and not force else None
    try:
        with kept_predictions(preds, force) as staging:
            result = run_one(name, source, train_split, config, cfg_scale=cfg_scale, weights=weights,
                             clips=clips, jobs=jobs, predictions_dir=staging, threads=threads,
                             extra=extra, check_configuration=check, device=device, batch=batch)
    except Unchanged:
        click.echo(f"skip {path} (same configuration; --force re-runs)")
        return None
    if preds is not None:
        result = predictions_at(result, preds)
    return written(result, path, per_clip)


def written(result: EvalResult, path: Path, per_clip: bool) -> EvalResult:
    """``result`` saved to ``path`` (atomically; per-clip rows dropped unless ``per_clip``), said on one line."""
    click.echo(summary(result).splitlines()[0] + f" -> {path}")
    save_result(result if per_clip else without_per_clip(result), path)
    return result


def runs_to_files() -> Callable:
    """:func:`run_to_file`, or while a cluster is active (``--scheduler``) a :class:`~dyadbench.cli.cluster.ClusterSweep`
    taking the same arguments, which sends each run as one task; its ``finish()`` writes the results."""
    return ClusterSweep(reuse_check, written, Unchanged) if distributed.active() is not None else run_to_file
