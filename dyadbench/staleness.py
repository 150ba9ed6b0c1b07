"""Provenance staleness: does a result file still describe what the current code and data would produce?

For each result file, :class:`Checker` rebuilds what a re-run with the file's recorded settings
(:class:`RecordedRun`) would record, and compares:

- the model's version and weights digest (:class:`~dyadbench.protocol.interface.ModelInfo`), from the model
  built as the run built it: the same registry name, layout and turn length; the same weights (the model's
  default checkpoint when the file names it, else the recorded ``--weights`` file while it exists); for
  baselines fitted on a train split, the same train split (fits come from their cache, see
  :mod:`baselines.fitting`). Every result file records these two, old ones included.
- for files that record a configuration (:mod:`dyadbench.protocol.run_configuration`): the whole
  configuration, in particular the content digest of the evaluated clips
  (:func:`dyadbench.provenance.split_digest`; for the embedded corpus it follows from the generator's
  identity) and the train split's digest.

Verdicts (:class:`Verdict`): ``current`` (everything recorded matches), ``stale`` (a recorded value
differs; ``reasons`` say which, e.g. ``the model's version differs (was 1, now 2)``) and ``unverified``
(nothing recorded contradicts the current state, but something could not be compared: the file predates
provenance and records no data digest, or its data folder, weights file or train split is not available
here). A :class:`Checker` caches built models and data digests for its lifetime. With
``generate=False`` (``dyadbench leaderboard``) it never generates an embedded corpus split that is not
in the cache: runs that need one are ``unverified``; ``dyadbench sweep --stale`` generates them.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Callable

from dyadbench.datasets.base import ClipSource
from dyadbench.errors import ConfigError, InputError
from dyadbench.protocol.config import ProtocolConfig
from dyadbench.protocol.perturbations import parse_all
from dyadbench.protocol.interface import ModelInfo, ModelOptions
from dyadbench.protocol.run_configuration import differences, requested_configuration
from dyadbench.protocol.train_split import TrainSplit, train_record
from dyadbench.provenance import split_digest
from dyadbench.registry import DATASETS
from dyadbench.results import EvalResult, load_result

CURRENT, STALE, UNVERIFIED = "current", "stale", "unverified"
REPO = Path(__file__).resolve().parents[1]


def _embedded_roots() -> dict[str, Callable[[], Path]]:
    """Where each embedded corpus keeps its generated splits (imported lazily: keeps --help light)."""
    from dyadbench.datasets.synthetic_gaze import synthetic_root  # noqa: PLC0415
    from dyadbench.datasets.synthetic import corpus_root, corpus_root_v2  # noqa: PLC0415

    return {"synthetic": corpus_root, "synthetic-v2": corpus_root_v2, "synthetic-gaze": synthetic_root}


class Unavailable(Exception):
    """Something a comparison needs is not available here (the message says what)."""


@dataclass(frozen=True)
class RecordedRun:
    """The settings a result file records, enough to run it again (``dyadbench sweep --stale``).

    ``root``: the data root to open (None: the embedded corpus); ``train``: (dataset, root) of the train
    split (None: not recorded, for files written before provenance on data not embedded); ``weights``: the
    recorded checkpoint path (None: the model has none or used its default, which
    :meth:`Checker.weights` tells apart); ``clips``: the recorded ``--clips`` (old files: the number of
    clips run); ``per_clip``: whether the file keeps per-clip rows (else it was written with --no-per-clip).
    """

    model: str
    layout: str
    dataset: str
    split: str
    root: str | None
    clips: int | None
    config: ProtocolConfig
    cfg_scale: float
    weights: str | None
    train: tuple[str, str | None] | None
    allow_overlap: bool
    per_clip: bool


def recorded_run(result: EvalResult) -> RecordedRun:
    """The settings of ``result``: from its configuration, or for older files from its records (the
    embedded corpora's cache folders then count as the embedded corpus, opened without a root, whose train
    split a fitted model used; for other data the train split is unknown)."""
    p, recorded = result.protocol, result.configuration
    config = ProtocolConfig(turn_seconds=p.turn_seconds, context=p.context, tail=p.tail,
                            history_agent=p.history_agent, seed=p.seed,
                            perturbations=parse_all(p.perturbations), noise_scale=p.noise_scale,
                            speech_norm=p.speech_norm)
    if recorded is not None:
        dataset, root, clips = recorded["dataset"], recorded["root"], recorded["clips"]
        train = recorded["train"] or {"dataset": dataset, "root": root}
        train = (train["dataset"], train["root"])
        model = recorded["model"]
    else:
        dataset, clips, model = result.data.dataset, result.data.clips, result.model.name
        embedded = dataset in _embedded_roots()
        root = None if embedded else result.data.root
        train = (dataset, None) if embedded else None
    return RecordedRun(model=model, layout=result.model.layout, dataset=dataset, split=result.data.split,
                       root=root, clips=clips, config=config, cfg_scale=p.cfg_scale,
                       weights=result.model.weights_path, train=train,
                       allow_overlap=bool((result.data.train or {}).get("overlap")), per_clip=bool(result.per_clip))


@dataclass(frozen=True)
class Verdict:
    """How a result file compares with the current state: ``status`` is one of CURRENT, STALE, UNVERIFIED;
    ``reasons``: what differs (stale) or what could not be compared (unverified)."""

    path: Path
    model: str
    status: str
    reasons: tuple[str, ...] = ()

    def line(self) -> str:
        """One line naming the file, the model and the reasons."""
        return f"{self.path} ({self.model}): {'; '.join(self.reasons)}"


class Checker:
    """Classifies result files (see the module docstring); models and digests are cached per checker."""

    def __init__(self, generate: bool = True):
        self.generate = generate
        self._models: dict[tuple, tuple[ModelInfo, dict | None]] = {}
        self._data: dict[tuple, tuple[ClipSource, str]] = {}

    def check(self, path: Path) -> Verdict:
        """The verdict on one result file (an unreadable file raises the loader's InputError)."""
        result = load_result(path)
        if result.external:
            return Verdict(path, result.model.name, UNVERIFIED, ("predictions made outside dyadbench (dyadbench "
                                                                 "score): no run to compare with",))
        run = recorded_run(result)
        try:
            info, train = self.model(run)
        except Unavailable as exc:
            return Verdict(path, run.model, UNVERIFIED, (f"the model could not be rebuilt here: {exc}",))
        recorded = {"model_version": result.model.version, "weights_digest": result.model.weights_digest}
        changed = differences(recorded, {"model_version": info.version, "weights_digest": info.weights_digest})
        if changed:
            return Verdict(path, run.model, STALE, tuple(changed))
        if result.configuration is None:
            return Verdict(path, run.model, UNVERIFIED, ("the file records no data digest (written before "
                                                         "results recorded their provenance)",))
        try:
            source, digest = self.data(run)
        except Unavailable as exc:
            return Verdict(path, run.model, UNVERIFIED, (str(exc),))
        current = requested_configuration(run.model, info, source, run.clips, run.config, run.cfg_scale,
                                          digest, train)
        changed = differences(result.configuration, current)
        return Verdict(path, run.model, STALE if changed else CURRENT, tuple(changed))

    def available(self, dataset: str, root: str | None, split: str) -> None:
        """Raise :class:`Unavailable` when opening the split would fail or, without ``generate``, would
        generate an embedded corpus split that is not in the cache."""
        if root is not None:
            if not Path(root).exists():
                raise Unavailable(f"its data folder {root} no longer exists")
            return
        embedded = _embedded_roots().get(dataset)
        if embedded is not None and not self.generate and not (embedded() / split).is_dir():
            raise Unavailable(f"the embedded {dataset} {split} split is not in the cache "
                              f"(`dyadbench sweep --stale` generates it)")

    def data(self, run: RecordedRun) -> tuple[ClipSource, str]:
        """The evaluated split of ``run`` and the content digest of its clips (its first ``clips``)."""
        key = (run.dataset, run.root, run.split, run.clips)
        if key not in self._data:
            self.available(run.dataset, run.root, run.split)
            try:
                source = open_split(run.dataset, run.root, run.split)
            except (ConfigError, InputError) as exc:  # e.g. an in-memory split, or a folder changed since
                raise Unavailable(f"its data cannot be opened here: {exc}") from None
            ids = source.clip_ids()
            self._data[key] = source, split_digest(source, ids if run.clips is None else ids[:run.clips])
        return self._data[key]

    def train_split(self, run: RecordedRun) -> TrainSplit:
        """The opener of the train split ``run`` was fitted on (unavailable, with the reason, when it
        cannot be opened here)."""
        if run.train is None:
            return TrainSplit(run.dataset, None, unavailable="the file does not record the train split its model "
                                                             "was fitted on (written before results recorded it)")
        dataset, root = run.train
        try:
            self.available(dataset, root, "train")
        except Unavailable as exc:
            return TrainSplit(dataset, None, run.allow_overlap, unavailable=f"the train split: {exc}")
        return TrainSplit(dataset, None if root is None else Path(root), run.allow_overlap)

    def weights(self, run: RecordedRun) -> Path | None:
        """The ``--weights`` the run used: None for none or the model's default checkpoint, else the
        recorded file (:class:`Unavailable` when it no longer exists)."""
        if run.weights is None:
            return None
        default = self.model_with(run, None)[0].weights_path
        if default is not None and _same_checkpoint(run.weights, default):
            return None
        for candidate in (Path(run.weights), REPO / run.weights):
            if candidate.is_file():
                return candidate
        raise Unavailable(f"its weights file {run.weights} no longer exists")

    def model(self, run: RecordedRun) -> tuple[ModelInfo, dict | None]:
        """(model info, train split record) of the model built with the run's weights and train split."""
        return self.model_with(run, self.weights(run))

    def model_with(self, run: RecordedRun, weights: Path | None) -> tuple[ModelInfo, dict | None]:
        """(model info, train split record) of ``run``'s model built with ``weights``, cached."""
        from dyadbench.protocol.runner import build_model  # noqa: PLC0415  (imports the scoring stack)

        key = (run.model, run.layout, run.config.turn_seconds, run.config.seed, run.cfg_scale, weights, run.train,
               run.dataset)
        if key not in self._models:
            train = self.train_split(run)
            options = ModelOptions(weights=weights, seed=run.config.seed, cfg_scale=run.cfg_scale,
                                   train_split=train, dataset=run.dataset,
                                   extra={"layout": run.layout, "turn_seconds": run.config.turn_seconds})
            try:
                info = build_model(run.model, options).info
            except (ConfigError, InputError, OSError, ImportError) as exc:
                raise Unavailable(str(exc)) from None
            self._models[key] = info, train_record(train)
        return self._models[key]


def open_split(dataset: str, root: str | None, split: str) -> ClipSource:
    """Split ``split`` of ``dataset`` at ``root`` (None: the embedded corpus), as a run opens it."""
    return DATASETS.load(dataset)(None if root is None else Path(root), split)


def _same_checkpoint(recorded: str, default: str) -> bool:
    """True when a recorded checkpoint path names the model's default checkpoint: the same file, or the
    same path inside the repository of another checkout (results committed from elsewhere)."""
    default_path = Path(default).resolve()
    if Path(recorded).resolve() == default_path:
        return True
    try:
        inside = default_path.relative_to(REPO).parts
    except ValueError:
        return False
    return Path(recorded).parts[-len(inside):] == inside


def check_files(paths: list[Path], checker: Checker) -> list[Verdict]:
    """The verdict on every file of ``paths``, in order."""
    return [checker.check(path) for path in paths]
