"""Which shipped checkpoint a reference model loads when the run gives no ``--weights``.

The small checkpoints shipped with the package are trained on an embedded corpus, one per corpus version:
``<stem>.pt`` on ``synthetic`` (v1) and ``<stem>-v2.pt`` on ``synthetic-v2``. A run on an embedded corpus
loads the checkpoint trained on that corpus, so each corpus's committed rows stay reproducible (and
:mod:`dyadbench.staleness` finds them current). Every other run (a real dataset, or code that names no
dataset) loads the checkpoint of the default embedded corpus, :data:`dyadbench.registry.DEFAULT_EMBEDDED`,
except a dataset of another motion layout for which the model ships its own checkpoint (``<stem>-seamless.pt``
for ``seamless``, trained on the synthetic corpus written in that layout): a model without one loads the
default and refuses the layout, naming the file.
"""

from __future__ import annotations

from pathlib import Path

from dyadbench.registry import DEFAULT_EMBEDDED

CHECKPOINT_SUFFIX = {"synthetic": "", "synthetic-v2": "-v2"}
LAYOUT_SUFFIX = {"seamless": "-seamless"}  # datasets of another motion layout: used where the file is shipped


def shipped_checkpoint(directory: Path, stem: str, dataset: str | None) -> Path:
    """``directory / <stem><suffix>.pt`` for the corpus ``dataset`` was trained on (see the module doc)."""
    if dataset in LAYOUT_SUFFIX and (own := directory / f"{stem}{LAYOUT_SUFFIX[dataset]}.pt").is_file():
        return own
    corpus = dataset if dataset in CHECKPOINT_SUFFIX else DEFAULT_EMBEDDED
    return directory / f"{stem}{CHECKPOINT_SUFFIX[corpus]}.pt"
