"""``dyadbench eval``: run one model through the streaming protocol over a split and score it."""

from __future__ import annotations

import functools
import io
import math
from dataclasses import replace
from pathlib import Path
from typing import Callable

import click

from dyadbench import atomic
from dyadbench.cli.cluster import scheduler_option
from dyadbench.cli.options import NON_NEGATIVE, POSITIVE, SEED, PerturbationSpec, check_cfg_scale, torch_device
from dyadbench.cli.splits import ON_DISK, open_splits, split_help
from dyadbench.datasets.base import ClipSource, InMemorySource
from dyadbench.errors import ConfigError, InputError
from dyadbench.outputs import OwnedFolder, check_cache, kept_on_failure
from dyadbench.protocol.config import HISTORY_AGENT, SPEECH_NORMS, TAILS, ProtocolConfig, variant_label
from dyadbench.protocol.interface import ModelOptions
from dyadbench.protocol.perturbations import variant_part
from dyadbench.registry import DATASETS, DEFAULT_EMBEDDED, MODELS
from dyadbench.results import EvalResult, load_result
from dyadbench.scoring import policy

EMBEDDED = DEFAULT_EMBEDDED
#: --batch default, from the batch-size sweep in benchmarks/results/batched_streaming.md (n = 7, one thread): TIMAR
#: levels off from batch 4 (4 and 8 equal within the noise), StyGazeTalk still gains at 8 (its 8 gaze-head test
#: sessions: 2.4x the turns/s of batch 1, against 1.8x at batch 4).
DEFAULT_BATCH = 8


def data_options(f: Callable) -> Callable:
    """--data / --dataset / --train / --allow-train-overlap / --clips / --jobs / --threads / --batch, shared by ``eval``
    and ``sweep`` (see :mod:`dyadbench.cli.splits`)."""
    options = [
        click.option("--data", "data", type=click.Path(exists=True, file_okay=False, path_type=Path), default=None,
                     help="Dataset root (e.g. a DualTalk folder holding train/ test/ ood/), or one split folder "
                          "(evaluated as the split its name says; it holds no train split). Without it the "
                          "embedded synthetic corpus is used (generated into the cache on first use)."),
        click.option("--train", "train", type=click.Path(exists=True, file_okay=False, path_type=Path),
                     default=None,
                     help="Train split for models fitted on one (baselines): a dataset root (its train/) or a "
                          "split folder of the same layout. Default: the train split of the --data root or of "
                          "the embedded corpus; needed when --data is a single split folder."),
        click.option("--allow-train-overlap", "allow_train_overlap", is_flag=True,
                     help="Run even when the train split holds evaluated clips (compared by content). The "
                          "result records the overlap and leaderboards flag the row and never rank it."),
        click.option("--dataset", default=None, type=click.Choice(DATASETS.names()),
                     help="Dataset adapter. Default: 'synthetic' without --data, 'dualtalk' with --data."),
        click.option("--clips", default=None, type=click.IntRange(min=1),
                     help="Only the first N clips of the split (sorted ids), for quick runs."),
        click.option("--jobs", "-j", default=1, show_default=True, type=click.IntRange(min=1),
                     help="Worker processes for streaming clips and for scoring."),
        click.option("--threads", default=None, type=click.IntRange(min=1),
                     help="CPU threads per process (recorded). Default: the libraries' own with --jobs 1, "
                          "1 per worker otherwise. Use 1 when other jobs share the machine: small models "
                          "stream fastest on one thread, and more threads than free cores can slow "
                          "streaming down about tenfold."),
        click.option("--batch", default=DEFAULT_BATCH, show_default=True, type=click.IntRange(min=1),
                     help="Directions (clip x participant) streamed together, their turns handed to the model in "
                          "one call (per process). Predictions are those of streaming one direction at a time, "
                          "so it is not recorded; models that batch their forward passes (TIMAR, "
                          "TIMAR-stream, DualTalk, SFMS, StyGazeTalk) run faster, the others loop over the batch. "
                          "1: one at a time."),
    ]
    return functools.reduce(lambda g, opt: opt(g), reversed(options), f)


def protocol_options(f: Callable) -> Callable:
    """--turn-seconds / --tail / --history-agent / --seed / --cfg-scale / --weights / --wav2vec / --device /
    --speech-norm /
    --perturb / --noise-scale."""
    options = [
        click.option("--turn-seconds", default=1.0, show_default=True, type=POSITIVE,
                     help="Turn length in seconds (must hold whole frames and samples; 1 s = 25 frames)."),
        click.option("--tail", default="truncate", show_default=True, type=click.Choice(TAILS),
                     help="Frames after the last whole turn: truncate (published TIMAR numbers) or "
                          "pad-last (repeat the last predicted frame)."),
        click.option("--history-agent", default="masked", show_default=True, type=click.Choice(HISTORY_AGENT),
                     help="Agent motion in history turns: masked (TIMAR's published runs) or the model's "
                          "own earlier outputs."),
        click.option("--seed", default=0, show_default=True, type=SEED,
                     help="Run seed: per-stream model seeds derive from (seed, clip, agent); also seeds the "
                          "randomised metrics. Recorded in the result."),
        click.option("--cfg-scale", default=1.0, show_default=True, type=NON_NEGATIVE,
                     help="Classifier-free guidance scale (1 = off); only for models tagged 'guidance' in "
                          "`dyadbench models` (timar, timar-stream), refused for the others."),
        click.option("--weights", default=None, type=click.Path(exists=True, dir_okay=False, path_type=Path),
                     help="Checkpoint for models with weights (default: the model's shipped checkpoint). "
                          "timar also takes the released TIMAR checkpoint (converted in memory; "
                          "`dyadbench weights convert` writes it once as a native file)."),
        click.option("--wav2vec", "wav2vec", default=None,
                     type=click.Path(exists=True, file_okay=False, path_type=Path),
                     help="Local wav2vec 2.0 model folder for models with wav2vec speech features (the "
                          "released TIMAR: facebook/wav2vec2-large-960h-lv60-self). Never downloaded."),
        click.option("--device", default="cpu", show_default=True, callback=torch_device,
                     help="Where models with weights run: cpu, cuda or cuda:N (the released TIMAR and DualTalk "
                          "sizes want a GPU). Recorded in the result's environment."),
        click.option("--speech-norm", default="window", show_default=True, type=click.Choice(SPEECH_NORMS),
                     help="Waveform normalisation of wav2vec front ends: window (causal: the audio of the "
                          "turns handed over) or clip (the whole clip's mean and variance, as the released "
                          "TIMAR and DualTalk evaluations and their published numbers; reads future audio, "
                          "so the run is recorded as not strictly causal)."),
        click.option("--perturb", "perturb", multiple=True, type=PerturbationSpec(),
                     help="Corrupt what the model receives (never the ground truth), repeatable: "
                          "TARGET:KIND:OCCUPANCY[:BURST_S[:SNR_DB]] with TARGET partner-motion (KIND drop, gaussian, "
                          "laplace, uniform), partner-speech or agent-speech (silence, noise); bursts of mean "
                          "BURST_S seconds (default 1) cover OCCUPANCY of the stream; speech noise at SNR_DB "
                          "(default 60). E.g. partner-motion:drop:0.3, agent-speech:silence:1:4. Recorded; the "
                          "result file gets a variant label."),
        click.option("--noise-scale", "noise_scale", default=None, type=POSITIVE,
                     help="Motion-noise scale sigma for --perturb partner-motion noise [default: the mean "
                          "per-dimension std of the train split's motion, rounded to 3 decimals, as released]."),
    ]
    return functools.reduce(lambda g, opt: opt(g), reversed(options), f)


def wav2vec_extra(wav2vec: Path | None) -> dict:
    """The model option naming the local wav2vec 2.0 folder (none without --wav2vec)."""
    return {} if wav2vec is None else {"wav2vec_weights": str(wav2vec)}


def run_variant(config: ProtocolConfig, cfg_scale: float) -> str:
    """The result-file variant of a run: :func:`~dyadbench.protocol.config.variant_label` of its settings,
    then its input perturbations (:func:`dyadbench.protocol.perturbations.variant_part`)."""
    parts = [variant_label(turn_seconds=config.turn_seconds, tail=config.tail, history_agent=config.history_agent,
                           cfg_scale=cfg_scale, seed=config.seed, speech_norm=config.speech_norm),
             variant_part(config.perturbations, config.noise_scale)]
    return "+".join(p for p in parts if p)


#: ``--dataset`` of the ``dyadbench train`` commands: whose train split they read (see :func:`open_train_split`).
TRAIN_DATASET = click.option(
    "--dataset", default=None, type=click.Choice(DATASETS.names()),
    help=f"Dataset whose train split to read. Default: '{EMBEDDED}' (the embedded corpus, generated into the "
         f"cache on first use) without --data, 'dualtalk' with --data. E.g. --dataset synthetic-v2.")


def open_train_split(data: Path | None, dataset: str | None, clips: int | None = None) -> ClipSource:
    """The train split a ``dyadbench train`` command reads: ``--data``'s (its layout named by ``--dataset``,
    default DualTalk) or, without ``--data``, the embedded corpus ``--dataset`` names (default ``EMBEDDED``);
    with ``clips``, only its first ``clips`` clips (held in memory)."""
    from dyadbench.protocol.runner import open_dataset_split  # noqa: PLC0415

    source = open_dataset_split(resolve_dataset(data, dataset), data, "train")
    if clips is None:
        return source
    return InMemorySource([source.load(c) for c in source.clip_ids()[:clips]], dataset=source.dataset,
                          split="train")


def resolve_dataset(data: Path | None, dataset: str | None) -> str:
    name = dataset or ("dualtalk" if data is not None else EMBEDDED)
    if data is None and name not in ON_DISK:
        raise ConfigError(f"--dataset {name} needs --data DIR (only the embedded corpora need none)")
    return name


def run_one(model: str, source: ClipSource, train: Callable[[], ClipSource], config: ProtocolConfig, *,
            cfg_scale: float, weights: Path | None, clips: int | None, jobs: int,
            predictions_dir: Path | None, extra: dict | None = None, threads: int | None = None,
            check_configuration: Callable[[dict], None] | None = None, device: str = "cpu",
            batch: int = 1) -> EvalResult:
    """:func:`dyadbench.protocol.runner.evaluate` with the command line's options."""
    from dyadbench.protocol.runner import evaluate  # noqa: PLC0415

    options = ModelOptions(weights=weights, seed=config.seed, cfg_scale=cfg_scale, train_split=train,
                           device=device, dataset=source.dataset, extra=dict(extra or {}))
    return evaluate(model, source, config, options=options, clips=clips, jobs=jobs,
                    predictions_dir=predictions_dir, threads=threads, check_configuration=check_configuration,
                    batch=batch)


def style_reference(source: ClipSource, style_from: str) -> str | object:
    """--style-from: an existing file path as is, else the motion of that session (clip id) of ``source``."""
    if Path(style_from).is_file():
        return style_from
    if style_from not in source.clip_ids():
        raise ConfigError(f"--style-from {style_from!r} is neither a file nor a session of "
                          f"{source.dataset}/{source.split}")
    return source.load(style_from).participants[0].motion


def summary(result: EvalResult) -> str:
    """Coverage line and a metric / raw / scaled table in the suite's column order."""
    flags = f" [{result.flags()}: not ranked]" if result.flags() else ""
    lines = [f"[{result.suite}] {result.model.name}{' (ORACLE)' if result.model.oracle else ''}{flags} on "
             f"{result.data.dataset}/{result.data.split}, {result.protocol.name} n={result.protocol.context}: "
             f"{result.coverage.get('scored', len(result.per_clip))} of {result.data.items} predictions scored"
             + (f", {len(result.excluded)} excluded" if result.excluded else ""),
             f"wall {result.timing.wall_s:.1f} s, mean per-turn latency "
             f"{result.timing.mean_turn_latency_s * 1e3:.3f} ms over {result.timing.turns} turns"]
    keys = list(result.scaling) or list(result.metrics)
    width = max(len(k) for k in keys)
    lines.append(f"{'metric'.ljust(width)}  {'raw':>12}  {'scaled':>12}")
    for k in keys:
        lines.append(f"{k.ljust(width)}  {_num(result.metrics.get(k)):>12}  {_num(result.scaled.get(k)):>12}")
    return "\n".join(lines)


def _num(v: float | None) -> str:
    return "nan" if v is None or (isinstance(v, float) and math.isnan(v)) else f"{v:.6g}"


def write_per_clip(result: EvalResult, path: Path) -> Path:
    buf = io.StringIO()
    result.per_clip_frame().to_csv(buf, index=False, float_format="%.10g")
    return atomic.write_text(path, buf.getvalue())


def save_result(result: EvalResult, path: Path, destination: Path | None = None) -> Path:
    """Write ``result`` to ``path``; when that fails, keep it under the system's temporary folder and raise
    an OutputError naming ``destination`` (default ``path``: where the user asked for it) and the kept file."""
    with kept_on_failure(destination or path, lambda: atomic.to_json(result.to_dict())):
        return result.write(path)


def predictions_at(result: EvalResult, folder: Path) -> EvalResult:
    """The result recording ``folder`` as its predictions (written aside, then moved there)."""
    return replace(result, predictions=str(folder))


def is_eval_output(folder: Path) -> bool:
    """True for a folder ``eval --out`` wrote before output folders carried a marker: its result.json loads."""
    try:
        load_result(folder / "result.json")
    except InputError:
        return False
    return True


def eval_output(out: Path, force: bool) -> OwnedFolder:
    """The ``--out`` folder of ``eval``, owned by one run (:class:`dyadbench.outputs.OwnedFolder`)."""
    return OwnedFolder(out, "eval", force=force, label=f"--out {out}", legacy=is_eval_output)


def is_predictions_folder(folder: Path) -> bool:
    """True for a folder of ``<stem>.npy`` prediction files only (a run's kept predictions)."""
    return all(p.suffix == ".npy" and p.is_file() for p in folder.iterdir())


@click.command("eval")
@click.option("--model", "model", required=True, help=f"Registered model ({', '.join(MODELS.names())}).")
@click.option("--split", default=None,
              help=split_help("Split of the dataset to evaluate [default: test; for a single split folder given as "
                              "--data, that folder, recorded under its name]."))
@click.option("--context", "-n", default=7, show_default=True, type=click.IntRange(min=0),
              help="History turns n given with the current turn (0 = none; TIMAR's main results use 7).")
@protocol_options
@data_options
@click.option("--style-from", "style_from", default=None,
              help="Style transfer (gaze-head models with a style encoder, e.g. stygazetalk): a session id of "
                   "the evaluated split, or a gaze-layout <session>.npz; its style conditions every window.")
@click.option("--out", "out", type=click.Path(file_okay=False, path_type=Path), default=None,
              help="Output folder: predictions/<clip>_speakerK.npy, result.json, per_clip.csv "
                   "[default: runs/<model>_<dataset>_<split>_n<context>[@<variant>]]. Written aside and swapped in when "
                   "complete: it then holds this run's files only, and an interrupted run leaves the "
                   "previous output untouched.")
@click.option("--force", is_flag=True,
              help="Replace --out even when it holds files that are not a previous eval output.")
@scheduler_option
def eval_command(model: str, split: str | None, context: int, turn_seconds: float, tail: str,
                 history_agent: str, seed: int, cfg_scale: float, weights: Path | None, wav2vec: Path | None,
                 device: str, speech_norm: str, perturb: tuple, noise_scale: float | None, data: Path | None,
                 dataset: str | None, train: Path | None,
                 allow_train_overlap: bool, clips: int | None, jobs: int, threads: int | None, batch: int,
                 style_from: str | None, out: Path | None, force: bool) -> None:
    """Run MODEL through the progressive-context streaming protocol over one split and score it.

    \b
    Both directions of every clip are generated (speaker1 given speaker2, and the reverse; on
    Learning2Listen only the listener), written in the DualTalk/TIMAR prediction layout (so `dyadbench
    score OUT/predictions --gt <split folder>` reproduces the numbers) and scored with the suite of the
    motion layout (flame56: DualTalk/TIMAR; gaze7: gaze-head), or the dataset's own (l2l: the L2L line).
    Example:
      dyadbench eval --model mean-frame --split test --context 7 --clips 20
    """
    MODELS.get(model)
    check_cfg_scale([model], cfg_scale)
    config = ProtocolConfig(turn_seconds=turn_seconds, context=context, tail=tail, history_agent=history_agent,
                            seed=seed, speech_norm=speech_norm, perturbations=perturb, noise_scale=noise_scale)
    name = resolve_dataset(data, dataset)
    check_cache()
    given = None if out is None else eval_output(out, force).check()  # before reading or digesting any data
    source, train_split = open_splits(data, name, split, train=train, allow_overlap=allow_train_overlap)
    variant = run_variant(config, cfg_scale)
    out = out or Path("runs") / (f"{model}_{name}_{source.split}_n{context}" + (f"@{variant}" if variant else ""))
    with (given or eval_output(out, force)).writing() as staging:
        extra = wav2vec_extra(wav2vec)
        if style_from is not None:
            extra["style_from"] = style_reference(source, style_from)
        result = run_one(model, source, train_split, config, cfg_scale=cfg_scale, weights=weights, clips=clips,
                         jobs=jobs, predictions_dir=staging / "predictions", extra=extra, threads=threads,
                         device=device, batch=batch)
        result = predictions_at(result, out / "predictions")
        save_result(result, staging / "result.json", out / "result.json")
        write_per_clip(result, staging / "per_clip.csv")
    click.echo(summary(result))
    for note in result.notes:  # implausible values (dyadbench.scoring.policy) are also said on stderr
        if note.startswith(policy.WARNING):
            click.echo(note, err=True)
    click.echo(f"wrote {out / 'predictions'}/ ({result.data.items} files), {out / 'result.json'} and "
               f"{out / 'per_clip.csv'}")
