"""The train split a model is fitted on: one explicit source, checked against the evaluated clips.

:class:`TrainSplit` is what ``dyadbench eval`` and ``sweep`` give models as
:attr:`~dyadbench.protocol.interface.ModelOptions.train_split`: a picklable opener of the train split of
the evaluated dataset's root, of the embedded corpus, or of ``--train DIR``; for a single split folder
given alone (which holds no train split) it opens nothing and says to pass ``--train``, so only models
fitted on a train split are refused. :func:`~dyadbench.protocol.runner.evaluate` gives each run a fresh
copy bound to the clips it evaluates (:func:`bind_train_split`). The first time the model opens it,
every evaluated clip is compared by content (:func:`dyadbench.provenance.shared_clips`) with the train
split: a shared clip refuses the run, unless ``allow_overlap`` (``--allow-train-overlap``). The opener
then keeps a :attr:`~TrainSplit.record` of the train split (dataset, split, root, content digest,
clips, shared clips), which the result stores (``data.train``); a result with shared clips is flagged
(:meth:`dyadbench.results.EvalResult.flags`) and never ranked in a leaderboard.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path
from typing import Callable, Iterable

from dyadbench.datasets.base import ClipSource
from dyadbench.errors import ConfigError
from dyadbench.provenance import root_identity, shared_clips, split_digest
from dyadbench.registry import DATASETS

SHOWN = 3  # shared clip ids named in an error or a note


def where(source: ClipSource) -> str:
    """A split as a user knows it: its folder, or dataset/split for generated and in-memory splits."""
    return str(source.root) if source.root is not None else f"{source.dataset}/{source.split}"


@dataclass
class TrainSplit:
    """Opener of the train split ``DATASETS[dataset](root, "train")`` (see the module docstring).

    ``unavailable``: why there is no train split (the opener then raises it as a ConfigError).
    ``evaluated`` / ``evaluated_ids``: the clips of the run (:func:`bind_train_split`).
    ``record``: set when first opened (see :func:`train_record`).
    """

    dataset: str
    root: Path | None
    allow_overlap: bool = False
    unavailable: str | None = None
    evaluated: ClipSource | None = None
    evaluated_ids: tuple[str, ...] = ()
    record: dict | None = None

    def __call__(self) -> ClipSource:
        if self.unavailable is not None:
            raise ConfigError(self.unavailable)
        source = DATASETS.load(self.dataset)(self.root, "train")
        if self.record is None:
            self.record = self._checked(source)
        return source

    def _checked(self, train: ClipSource) -> dict:
        """The train split's record; a ConfigError naming both splits when it shares evaluated clips."""
        shared = (shared_clips(train, self.evaluated, self.evaluated_ids) if self.evaluated is not None
                  else None)
        if shared and not self.allow_overlap:
            shown = ", ".join(e if e == t else f"{e} (= train {t})" for e, t in shared[:SHOWN])
            more = f" and {len(shared) - SHOWN} more" if len(shared) > SHOWN else ""
            raise ConfigError(
                f"the train split {where(train)} holds {len(shared)} of the {len(self.evaluated_ids)} clips "
                f"evaluated from {where(self.evaluated)} ({shown}{more}): the model would be scored on its "
                f"own training data. Pass a separate train split with --train DIR, or --allow-train-overlap "
                f"to run anyway (the result is then flagged and never ranked)")
        return {"dataset": train.dataset, "split": train.split, "root": root_identity(train),
                "digest": split_digest(train), "clips": len(train),
                "overlap": None if shared is None else len(shared),
                "overlap_clips": [] if shared is None else [e for e, _ in shared[:SHOWN]]}


def bind_train_split(opener: Callable[[], ClipSource] | None, evaluated: ClipSource,
                     ids: Iterable[str]) -> Callable[[], ClipSource] | None:
    """A fresh, unopened copy of a :class:`TrainSplit` for one run over ``ids`` of ``evaluated``;
    any other opener unchanged."""
    if not isinstance(opener, TrainSplit):
        return opener
    return replace(opener, evaluated=evaluated, evaluated_ids=tuple(ids), record=None)


def train_record(opener: Callable[[], ClipSource] | None) -> dict | None:
    """The record of a :class:`TrainSplit` the model opened; None when it opened none (or another opener)."""
    return opener.record if isinstance(opener, TrainSplit) else None


def overlap_notes(record: dict | None) -> list[str]:
    """The result's note for a run whose train split shares evaluated clips (none otherwise)."""
    if not record or not record.get("overlap"):
        return []
    train = record["root"] or f"{record['dataset']}/{record['split']}"
    return [f"TRAIN OVERLAP: the train split {train} holds {record['overlap']} of the evaluated clips (e.g. "
            f"{', '.join(record['overlap_clips'])}); run with --allow-train-overlap: the scores are not "
            f"comparable with other runs and never ranked"]


def open_for(opener: Callable[[], ClipSource] | None, user: str, *, missing: str, hint: str = "") -> ClipSource:
    """The train split ``opener`` opens for ``user`` (a model or setting that needs it, named in messages): a
    ConfigError ``"<user> <missing>"`` when the run has none, or naming ``user`` and why it cannot be opened;
    ``hint`` (what to do instead) ends both messages."""
    tail = f"; {hint}" if hint else ""
    if opener is None:
        raise ConfigError(f"{user} {missing}{tail}")
    try:
        return opener()
    except ConfigError as exc:
        raise ConfigError(f"{user}: {exc}{tail}") from None
