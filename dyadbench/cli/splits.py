"""Which split ``eval`` and ``sweep`` evaluate, and which train split models are fitted on.

- Evaluated split: split ``--split`` (default ``test``) of the dataset root ``--data``, or of the embedded
  corpus without ``--data``. A split folder given alone as ``--data`` (e.g. ``DualTalk/test``) is that
  split and is named by the folder: without ``--split`` it is evaluated as such (``sweep`` without
  ``--splits`` runs it alone); an explicit ``--split``/``--splits`` naming another split is refused,
  since the folder holds no other.
- Train split, for models fitted on one (:class:`~dyadbench.protocol.train_split.TrainSplit`):
  ``--train DIR`` (a root: its ``train/``; or a split folder, used as is), else the train split of the
  ``--data`` root or of the embedded corpus. A split folder given alone has none: a model that needs one
  is refused and told to pass ``--train``; models with their own weights run. Whatever its source, a
  train split that holds evaluated clips is refused unless ``--allow-train-overlap``.
"""

from __future__ import annotations

from pathlib import Path

import click

from dyadbench.datasets.base import ClipSource, split_folder_mismatch
from dyadbench.protocol.train_split import TrainSplit
from dyadbench.registry import DATASETS

#: Splits ``sweep`` runs by default (on a dataset root or the embedded corpus).
SWEEP_SPLITS = ("test", "ood")
#: The splits of every registered dataset (:data:`dyadbench.registry.DATASETS`), for ``--help`` without importing
#: the adapters (a test checks them against each adapter's ``SPLITS``); the gaze layout's splits are the ones
#: its ``splits.csv`` names.
DATASET_SPLITS = {
    "synthetic": "train, val, test, ood", "synthetic-v2": "train, val, test, ood",
    "dualtalk": "train, test, ood", "l2l": "train, test", "react": "train, val, test",
    "seamless": "train, dev, test", "seamless-gaze": "train, dev, test",
    "gaze": "those its splits.csv names", "synthetic-gaze": "train, val, test, ood",
}


def split_help(what: str) -> str:
    """``--split``/``--splits`` help: ``what``, then every dataset's splits."""
    return f"{what} Splits: " + "; ".join(f"{name}: {splits}" for name, splits in DATASET_SPLITS.items()) + "."


#: The adapter reading the files of an embedded corpus from a folder on disk (``--train DIR`` with it).
ON_DISK = {"synthetic": "dualtalk", "synthetic-v2": "dualtalk", "synthetic-gaze": "gaze"}


def open_evaluated(dataset: str, data: Path | None, split: str | None) -> ClipSource:
    """Split ``split`` of ``data`` (None: test, or the split folder ``data`` itself), refusing another
    split's name for a split folder given alone."""
    from dyadbench.protocol.runner import open_dataset_split  # noqa: PLC0415  (keeps --help light)

    source = open_dataset_split(dataset, data, split)
    if source.single_split:
        if split is not None and split != source.split:
            raise split_folder_mismatch(data, source.split, split)
        click.echo(f"--data {data} is a single split folder: evaluated as split {source.split!r}", err=True)
    return source


def train_opener(dataset: str, data: Path | None, evaluated: ClipSource, train: Path | None,
                 allow_overlap: bool) -> TrainSplit:
    """The train split models of a run over ``evaluated`` are fitted on (see the module docstring)."""
    if train is not None:
        return TrainSplit(ON_DISK.get(dataset, dataset), train, allow_overlap)
    if evaluated.single_split:
        return TrainSplit(dataset, data, allow_overlap, unavailable=(
            f"it is fitted on a train split, but --data {data} is a single split folder ({evaluated.split!r}) "
            f"and holds none: pass --train DIR (a dataset root holding train/, or a train split folder)"))
    return TrainSplit(dataset, data, allow_overlap)


def _announce(data: Path | None, dataset: str) -> None:
    if data is None:
        click.echo(f"using the embedded {dataset} corpus ({DATASETS.get(dataset).target}); "
                   f"pass --data DIR for a dataset on disk", err=True)


def open_splits(data: Path | None, dataset: str, split: str | None, *, train: Path | None = None,
                allow_overlap: bool = False) -> tuple[ClipSource, TrainSplit]:
    """The evaluated split and the picklable opener of its train split (see the module docstring)."""
    _announce(data, dataset)
    source = open_evaluated(dataset, data, split)
    return source, train_opener(dataset, data, source, train, allow_overlap)


def sweep_splits(data: Path | None, dataset: str, splits: list[str] | None, *, train: Path | None = None,
                 allow_overlap: bool = False) -> list[tuple[ClipSource, TrainSplit]]:
    """:func:`open_splits` for every split of a sweep, all opened before any run (None: the split folder
    ``data`` alone, else :data:`SWEEP_SPLITS`)."""
    _announce(data, dataset)
    if splits is None:
        first = open_evaluated(dataset, data, None)
        sources = [first] if first.single_split else [first] + [
            open_evaluated(dataset, data, s) for s in SWEEP_SPLITS if s != first.split]
    else:
        sources = [open_evaluated(dataset, data, s) for s in splits]
    return [(source, train_opener(dataset, data, source, train, allow_overlap)) for source in sources]
