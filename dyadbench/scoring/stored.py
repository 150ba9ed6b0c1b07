"""Score items read back when they are scored: how ``eval`` scores a split without holding its predictions.

A :class:`StoredItem` names one scored direction by its stem and a picklable ``opener`` that reads it back
as a :class:`~dyadbench.scoring.report.ScoreItem` (``eval``: the prediction from the ``.npy`` file it wrote,
the ground truth from the clip source). A suite that scores item by item declares ``STREAMS_ITEMS = True``
in its module (:func:`streams_items`; the DualTalk/TIMAR suite) and opens each stored item only in the job
that scores it, so one item per worker is in memory at a time; suites with split-level statistics take
arrays in memory.
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass
from typing import Callable

from dyadbench.errors import InputError
from dyadbench.scoring.report import ScoreItem


@dataclass(frozen=True)
class StoredItem:
    """One item to score, read when needed: ``opener()`` returns its :class:`ScoreItem` (stem ``stem``);
    ``has_partner`` says whether that item carries the partner's ground truth."""

    stem: str
    has_partner: bool
    opener: Callable[[], ScoreItem]

    def load(self) -> ScoreItem:
        """The item's arrays, read now; an opener that returns another item -> InputError naming both."""
        item = self.opener()
        if item.stem != self.stem or (item.partner is not None) != self.has_partner:
            raise InputError(self.stem, f"stored item read back as {item.stem!r} "
                                        f"(partner {'present' if item.partner is not None else 'missing'})")
        return item


def streams_items(suite: str) -> bool:
    """Whether ``dyadbench.scoring.<suite>.score_arrays`` accepts :class:`StoredItem` s (``STREAMS_ITEMS``)."""
    return bool(getattr(importlib.import_module(f"dyadbench.scoring.{suite}"), "STREAMS_ITEMS", False))
