"""Run one model over one split: every evaluated direction of every clip, predictions written, then scored.

:func:`evaluate` builds the model from :data:`dyadbench.registry.MODELS`, streams every evaluated
direction (each participant the clip names as an agent, by default both) of every clip through
:func:`~dyadbench.protocol.streaming.stream_agent` (or the offline protocol for full-sequence models),
writes each prediction as ``<clip>_<agent>.npy`` (T', D) float32 — the DualTalk/TIMAR prediction
layout, so ``dyadbench score`` on the folder reproduces the numbers — and scores the same arrays with
the dataset's own suite where it names one (``ClipSource.suite``; Learning2Listen: the L2L line) and
otherwise the suite of the motion layout (flame56: DualTalk/TIMAR suite; gaze7: the gaze–head suite).
With ``jobs > 1`` clips are streamed in that many worker processes (each building its own model from
the same options; forked, or spawned once torch is loaded) and the suite scores with ``jobs`` workers
too.
Scores are memoised within a process by a digest of the scored arrays (:func:`score_items`), so a sweep
scores the byte-identical predictions of a history-free model once across context lengths; streaming
and timing are always run.
Memory: clips are streamed one at a time (``batch`` directions, or runs of clips per worker), and a suite
that scores item by item (``STREAMS_ITEMS``, :mod:`dyadbench.scoring.stored`; the DualTalk/TIMAR suite)
gets each direction as a :class:`~dyadbench.scoring.stored.StoredItem` read back from its ``.npy`` and the
source when it is scored (the digest is taken while streaming), so no split of predictions is held whole.
"""

from __future__ import annotations

import functools
import hashlib
import importlib
import os
import pickle
import shutil
import sys
import tempfile
import time
from collections import OrderedDict, deque
from dataclasses import dataclass, replace
from multiprocessing import get_context
from pathlib import Path
from typing import Callable, Iterator

import numpy as np
from tqdm import tqdm

from dyadbench import atomic
from dyadbench.arrays import load_npy
from dyadbench.datasets.base import ClipSource
from dyadbench.errors import ConfigError, InputError
from dyadbench.motion import LAYOUTS
from dyadbench.protocol.config import ProtocolConfig
from dyadbench.protocol.interface import ModelOptions, OfflineModel, StreamingModel
from dyadbench.protocol.noise_scale import resolve_noise_scale
from dyadbench.protocol.offline import run_offline
from dyadbench.protocol.perturbations import describe, perturbed_inputs
from dyadbench.protocol.run_configuration import requested_configuration
from dyadbench.protocol.streaming import StreamOutput, stream_agent, stream_agents
from dyadbench.protocol.train_split import bind_train_split, overlap_notes, train_record
from dyadbench.provenance import split_digest
from dyadbench.registry import DATASETS, MODELS
from dyadbench.results import (DataRecord, EvalResult, ModelRecord, ProtocolRecord, TimingRecord, environment,
                               utc_now)
from dyadbench.scoring.report import ScoreItem
from dyadbench.scoring.stored import StoredItem, streams_items
from dyadbench.workers import process_map

#: Metric suite of each motion layout (module dyadbench.scoring.<suite> provides score_arrays).
SUITE_OF_LAYOUT = {"flame56": "dualtalk", "gaze7": "gaze", "seamless": "seamless", "seamless-gaze": "seamless"}


def open_dataset_split(dataset: str, root: Path | None, split: str) -> ClipSource:
    """``DATASETS[dataset](root, split)``: a picklable way to name a split (used as ``train_split``)."""
    return DATASETS.load(dataset)(root, split)


@dataclass(frozen=True)
class _Streamed:
    """What one direction of one clip produced, with what the suite needs to score it."""

    output: StreamOutput
    item: ScoreItem
    clip_id: str
    agent: str


def build_model(name: str, options: ModelOptions) -> StreamingModel | OfflineModel:
    model = MODELS.load(name)(options)
    if not isinstance(model, (StreamingModel, OfflineModel)):
        raise ConfigError(f"model {name!r} factory returned {type(model).__name__}, "
                          f"not a StreamingModel or OfflineModel")
    return model


def run_direction(model: StreamingModel | OfflineModel, clip, agent: str, config: ProtocolConfig) -> StreamOutput:
    """Streaming protocol for streaming models, offline protocol for full-sequence models."""
    if isinstance(model, StreamingModel):
        return stream_agent(model, clip, agent, config)
    return run_offline(model, clip, agent, config)


def _score_item(clip, p, stem: str, pred: np.ndarray, keep_audio: bool) -> ScoreItem:
    """What the suite scores of agent ``p`` of (the unperturbed) ``clip`` given its prediction ``pred``."""
    partner = clip.partner_of(p.name)
    return ScoreItem(
        stem=stem, pred=pred, gt=np.asarray(p.motion, np.float32),
        partner=np.asarray(partner.motion, np.float32) if partner is not None else None,
        audio=np.asarray(p.audio, np.float32) if keep_audio else None, identity=p.identity,
        fps=clip.fps, sample_rate=clip.sample_rate)


def _streamed(clip, p, result: StreamOutput, keep_audio: bool) -> _Streamed:
    return _Streamed(result, _score_item(clip, p, result.stem, result.motion, keep_audio), clip.clip_id, p.name)


def read_back(source: ClipSource, clip_id: str, agent: str, path: Path, keep_audio: bool) -> ScoreItem:
    """The :class:`ScoreItem` of a direction whose prediction was written to ``path``: the same arrays as the
    one built while streaming (the file holds the float32 prediction; the clip is read again from ``source``)."""
    clip = source.load(clip_id)
    return _score_item(clip, clip.participant(agent), path.stem, load_npy(path), keep_audio)


def _seen(clip, agent: str, config: ProtocolConfig):
    """What the model receives of ``clip`` when ``agent`` is generated (perturbed inputs, if any)."""
    return perturbed_inputs(clip, agent, config.perturbations, config.seed, config.noise_scale)


def _stream_clip(model, source: ClipSource, clip_id: str, config: ProtocolConfig, keep_audio: bool) -> list[_Streamed]:
    clip = source.load(clip_id)
    return [_streamed(clip, p, run_direction(model, _seen(clip, p.name, config), p.name, config), keep_audio)
            for p in clip.agent_participants]


def _stream_clips_batched(model: StreamingModel, source: ClipSource, clip_ids: list[str], config: ProtocolConfig,
                          keep_audio: bool, batch: int) -> Iterator[list[_Streamed]]:
    """Yield, clip by clip in order, the streamed directions of ``clip_ids``, up to ``batch`` directions
    (of consecutive clips) streamed together (:func:`~dyadbench.protocol.streaming.stream_agents`); clips are
    read only as slots free up."""
    opened: deque = deque()  # (clip, participants) in the order their directions were handed over

    def directions():
        for clip_id in clip_ids:
            clip = source.load(clip_id)
            opened.append((clip, clip.agent_participants))
            for p in clip.agent_participants:
                yield _seen(clip, p.name, config), p.name

    done: list[_Streamed] = []
    for result in stream_agents(model, directions(), config, batch):
        clip, participants = opened[0]
        done.append(_streamed(clip, participants[len(done)], result, keep_audio))
        if len(done) == len(participants):
            opened.popleft()
            yield done
            done = []


_WORKER: dict = {}


def set_threads(threads: int) -> None:
    """Cap this process's CPU threads: the loaded BLAS/OpenMP pools (threadpoolctl), libraries loaded later
    (OMP_NUM_THREADS) and torch's intra-op pool if a model already imported torch."""
    from threadpoolctl import threadpool_limits  # noqa: PLC0415  (a scikit-learn dependency)

    os.environ["OMP_NUM_THREADS"] = str(threads)
    threadpool_limits(limits=threads)
    if "torch" in sys.modules:
        sys.modules["torch"].set_num_threads(threads)


def _init_worker(model_name: str, options: ModelOptions, source: ClipSource, config: ProtocolConfig,
                 keep_audio: bool, threads: int | None, batch: int) -> None:
    set_threads(threads or 1)  # workers share the machine: one thread each unless told otherwise
    _WORKER.update(model=build_model(model_name, options), source=source, config=config, keep_audio=keep_audio,
                   batch=batch)


def _worker_clips(clip_ids: list[str]) -> list[list[_Streamed]]:
    w = _WORKER
    return list(_stream_clips(w["model"], w["source"], clip_ids, w["config"], w["keep_audio"], w["batch"]))


def _stream_clips(model, source: ClipSource, clip_ids: list[str], config: ProtocolConfig, keep_audio: bool,
                  batch: int) -> Iterator[list[_Streamed]]:
    """Per clip, in order: one direction at a time (``batch`` 1, offline models) or ``batch`` together."""
    if batch > 1 and isinstance(model, StreamingModel):
        yield from _stream_clips_batched(model, source, clip_ids, config, keep_audio, batch)
    else:
        for clip_id in clip_ids:
            yield _stream_clip(model, source, clip_id, config, keep_audio)


def evaluate(model_name: str, source: ClipSource, config: ProtocolConfig, *, options: ModelOptions | None = None,
             clips: int | None = None, jobs: int = 1, predictions_dir: Path | None = None,
             progress: bool = True, threads: int | None = None,
             check_configuration: Callable[[dict], None] | None = None, batch: int = 1) -> EvalResult:
    """Run ``model_name`` over ``source`` under ``config`` and score it (see module docstring).

    ``predictions_dir``: where ``<stem>.npy`` files go (None: a temporary folder, removed after scoring).
    ``clips``: only the first N clips (sorted ids). The model's options get ``extra["layout"]`` and
    ``extra["turn_seconds"]`` from the split and the protocol.
    ``threads``: CPU threads per process (None: the libraries' default in-process, 1 per worker). Per-turn
    work of small models is too fine-grained to gain from threads, and threads beyond the free cores
    (another job running) can make streaming an order of magnitude slower.
    A :class:`~dyadbench.protocol.train_split.TrainSplit` in ``options.train_split`` is bound to the evaluated
    clips (a model fitted on some of them is refused unless it allows overlap) and recorded in the result.
    ``check_configuration``: called with the run's :func:`requested_configuration` once the model is built,
    before any clip is streamed (an exception it raises stops the run; ``sweep`` uses it to skip unchanged runs).
    ``batch``: directions of a streaming model streamed together (:func:`~dyadbench.protocol.streaming.stream_agents`;
    per process with ``jobs > 1``). It changes no prediction (each stream keeps its own state and random
    draws), so it is not part of the run's configuration.
    """
    started = time.perf_counter()
    ids = source.clip_ids()
    if clips is not None:
        if clips < 1:
            raise ConfigError(f"clips must be >= 1, got {clips}")
        ids = ids[:clips]
    if not ids:
        raise InputError(f"{source.dataset}/{source.split}", "the split has no clips")
    layout = source.load(ids[0]).layout
    if layout not in SUITE_OF_LAYOUT:
        raise ConfigError(f"no metric suite for motion layout {layout!r}")
    suite = source.suite or SUITE_OF_LAYOUT[layout]
    options = options or ModelOptions(seed=config.seed)
    options = replace(options, train_split=bind_train_split(options.train_split, source, ids),
                      extra={**options.extra, "layout": layout, "turn_seconds": config.turn_seconds})
    model = build_model(model_name, options)
    if threads is not None:
        set_threads(threads)
    if model.info.layout != layout:
        raise ConfigError(f"model {model_name!r} produces {model.info.layout} motion ({LAYOUTS[model.info.layout].dim} "
                          f"dims); the split is {layout} ({LAYOUTS[layout].dim} dims at {source.load(ids[0]).fps:g} fps)")
    config = resolve_noise_scale(config, options.train_split)
    train = train_record(options.train_split)
    data_digest = split_digest(source, ids)
    requested = requested_configuration(model_name, model.info, source, clips, config, options.cfg_scale,
                                        data_digest, train)
    if check_configuration is not None:
        check_configuration(requested)
    keep_audio = suite == "gaze"

    temporary = predictions_dir is None
    pred_dir = Path(tempfile.mkdtemp(prefix="dyadbench-preds-")) if temporary else Path(predictions_dir)
    pred_dir.mkdir(parents=True, exist_ok=True)
    items: list[ScoreItem | StoredItem] = []
    stored = streams_items(suite)
    digest = ItemsDigest(suite, config.seed)
    latencies: list[float] = []
    protocol_name = "streaming" if isinstance(model, StreamingModel) else "offline"
    try:
        bar = tqdm(total=len(ids), desc=f"{model_name} {source.dataset}/{source.split} n={config.context}",
                   unit="clip", disable=not progress)
        for streamed in _stream_all(model, model_name, options, source, ids, config, keep_audio, jobs, threads,
                                    batch):
            for s in streamed:
                path = pred_dir / f"{s.output.stem}.npy"
                atomic.save_npy(path, s.output.motion.astype(np.float32))
                digest.add(s.item)
                items.append(StoredItem(s.item.stem, s.item.partner is not None, functools.partial(
                    read_back, source, s.clip_id, s.agent, path, keep_audio)) if stored else s.item)
                latencies.extend(s.output.turn_latency_s)
            bar.update(1)
        bar.close()
        report, reused = score_items(suite, items, jobs=jobs, seed=config.seed,
                                     options=suite_options(suite, model.info), digest=digest.hexdigest())
    finally:
        if temporary:
            shutil.rmtree(pred_dir, ignore_errors=True)

    info = model.info
    model_s = float(np.sum(latencies))
    return EvalResult(
        model=ModelRecord(name=info.name, version=info.version, weights_digest=info.weights_digest,
                          weights_path=info.weights_path, oracle=bool(info.oracle), layout=info.layout,
                          config=dict(info.config)),
        data=DataRecord(dataset=source.dataset, split=source.split,
                        root=str(source.root) if source.root else None, clips=len(ids), items=len(items),
                        digest=data_digest, train=train),
        protocol=ProtocolRecord(name=protocol_name, turn_seconds=config.turn_seconds, context=config.context,
                                tail=config.tail, history_agent=config.history_agent,
                                cfg_scale=float(options.cfg_scale), seed=config.seed,
                                speech_norm=config.speech_norm, perturbations=describe(config.perturbations),
                                noise_scale=config.noise_scale),
        suite=suite, metrics=dict(report.metrics), scaled=report.scaled, scaling=report.scaling,
        per_clip=list(report.per_item), coverage=dict(report.coverage), excluded=list(report.excluded),
        notes=overlap_notes(train) + speech_norm_notes(config) + perturbation_notes(config) + skipped_notes(source)
        + list(report.notes)
        + ([f"scores reused: this process already scored byte-identical predictions "
            f"(sha256 {reused[:16]})"] if reused else []),
        predictions=None if temporary else str(pred_dir),
        timing=TimingRecord(wall_s=time.perf_counter() - started, model_s=model_s, turns=len(latencies),
                            mean_turn_latency_s=model_s / max(len(latencies), 1), threads=threads),
        environment={**environment(), "device": options.device}, created_utc=utc_now(), configuration=requested,
        uncertainty=dict(report.uncertainty), uncertainty_method=dict(report.uncertainty_method))


def speech_norm_notes(config: ProtocolConfig) -> list[str]:
    """The note a run under ``--speech-norm clip`` carries (none otherwise)."""
    if config.speech_norm != "clip":
        return []
    return ["speech-norm clip: models normalising waveforms read each clip's whole-waveform mean and variance "
            "(as the released TIMAR and DualTalk evaluations do); this reads future audio, so the run is not "
            "strictly causal"]


def perturbation_notes(config: ProtocolConfig) -> list[str]:
    """The note a perturbed run carries: what the model received and how its perturbations were seeded."""
    if not config.perturbations:
        return []
    scale = f"; motion noise scale sigma = {config.noise_scale:g}" if config.noise_scale is not None else ""
    return [f"perturbed inputs {describe(config.perturbations)} (dyadbench.protocol.perturbations; scored "
            f"against the unperturbed ground truth): each clip and participant seeded with "
            f"derive_seed({config.seed}, 'perturbation', clip, participant, signal, kind){scale}"]


def skipped_notes(source: ClipSource) -> list[str]:
    """The note of a split whose reader left dialogues out (``describe()["skipped_dyads"]``: e.g. Seamless
    Interaction dyads with an empty bundle, no movement features or one usable participant), with the count."""
    info = source.describe()
    if not info.get("skipped_dyads"):
        return []
    skipped, reasons = info["skipped_dyads"], [s["reason"] for s in info.get("skipped", [])]
    return [f"{skipped} dyad(s) of the split skipped by the reader, not evaluated (`dyadbench data validate` lists "
            f"each): {'; '.join(reasons[:3])}{' ...' if len(reasons) > 3 else ''}"]


_SCORE_MEMO: "OrderedDict[str, object]" = OrderedDict()
SCORE_MEMO_SIZE = 32


class ItemsDigest:
    """sha256 over the suite, the seed and every item's stem and arrays (what scoring depends on), taken one
    item at a time (:meth:`add`), so the items need not be held together."""

    def __init__(self, suite: str, seed: int):
        self._h = hashlib.sha256(f"{suite}\x1f{seed}".encode())

    def add(self, item: ScoreItem) -> None:
        h = self._h
        h.update(f"\x1e{item.stem}\x1f{item.identity}\x1f{item.fps}\x1f{item.sample_rate}".encode())
        for array in (item.pred, item.gt, item.partner, item.audio):
            if array is None:
                h.update(b"\x00")
            else:
                a = np.ascontiguousarray(array)
                h.update(f"{a.dtype}{a.shape}".encode())
                h.update(a.tobytes())

    def hexdigest(self) -> str:
        return self._h.hexdigest()


def items_digest(suite: str, seed: int, items: list[ScoreItem]) -> str:
    """:class:`ItemsDigest` of ``items`` in order."""
    digest = ItemsDigest(suite, seed)
    for item in items:
        digest.add(item)
    return digest.hexdigest()


def suite_options(suite: str, info) -> dict:
    """Keyword arguments of the suite's ``score_arrays`` that depend on the model: the suite module's
    ``model_options(info)`` where it defines one (:func:`dyadbench.scoring.gaze.model_options`), else none."""
    model_options = getattr(importlib.import_module(f"dyadbench.scoring.{suite}"), "model_options", None)
    return model_options(info) if model_options else {}


def score_items(suite: str, items: list[ScoreItem | StoredItem], *, jobs: int, seed: int,
                options: dict | None = None, digest: str | None = None):
    """``dyadbench.scoring.<suite>.score_arrays(items, **options)``, memoised in this process by
    :func:`items_digest` and the options (``digest``: the items' digest taken already, required for
    :class:`~dyadbench.scoring.stored.StoredItem` s).

    A history-free model gives byte-identical predictions at every context length; a sweep then scores
    them once. Returns (report, digest if the report was reused else None).
    """
    options = options or {}
    option_text = repr(sorted((name, getattr(value, "digest", value)) for name, value in options.items()))
    key = hashlib.sha256(((digest or items_digest(suite, seed, items)) + option_text).encode()).hexdigest()
    if key in _SCORE_MEMO:
        _SCORE_MEMO.move_to_end(key)
        return _SCORE_MEMO[key], key
    report = importlib.import_module(f"dyadbench.scoring.{suite}").score_arrays(items, jobs=jobs, seed=seed,
                                                                          **options)
    _SCORE_MEMO[key] = report
    while len(_SCORE_MEMO) > SCORE_MEMO_SIZE:
        _SCORE_MEMO.popitem(last=False)
    return report, None


def _stream_all(model, model_name, options, source, ids, config, keep_audio, jobs, threads, batch):
    """Yield, clip by clip in order, the streamed directions (in-process or in ``jobs`` workers, each streaming
    runs of consecutive clips, ``batch`` directions together)."""
    if batch < 1:
        raise ConfigError(f"batch must be >= 1, got {batch}")
    if jobs <= 1 or len(ids) == 1:
        yield from _stream_clips(model, source, ids, config, keep_audio, batch)
        return
    try:
        pickle.dumps((options, source))
    except Exception as exc:
        raise ConfigError(f"--jobs > 1 needs picklable model options and clip source ({exc}); "
                          f"use jobs=1") from None
    # Forked workers share the parent's code and memory; a process that has loaded torch spawns fresh ones
    # (forking after torch's thread pools have started is unsafe).
    # An error in a worker (a clip that cannot be read, a model that fails to build) is raised here as with
    # jobs=1 (dyadbench.workers.process_map).
    method = "spawn" if "torch" in sys.modules or sys.platform != "linux" else "fork"
    size = max(1, min(16, len(ids) // (4 * jobs)), -(-batch // 2))  # about a batch of directions per task
    runs = [ids[i:i + size] for i in range(0, len(ids), size)]
    for streamed in process_map(_worker_clips, runs, jobs=jobs, context=get_context(method),
                                initializer=_init_worker,
                                initargs=(model_name, options, source, config, keep_audio, threads, batch)):
        yield from streamed
