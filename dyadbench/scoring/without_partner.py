"""Scoring without the partner's ground truth, the same way in every suite that has partner-based metrics.

A suite declares which of its keys need the partner's ground truth (DualTalk: P-FD and rPCC,
:data:`dyadbench.metrics.dualtalk.PARTNER_KEYS`; L2L: P-FD and rPCC of the speaker,
:func:`dyadbench.metrics.l2l.partner_keys`). An item whose partner's ground truth is missing (the released
DualTalk demo clips each ship one participant's file) is scored on every other key; its partner-based keys
are NaN in its row, left out of those columns, listed under ``coverage["not_computable"]`` with the reason
(:func:`not_computable`), and the report's notes say so (:func:`notes`).
"""

from __future__ import annotations

from typing import Iterable, Mapping


def not_computable(missing: Mapping[str, str], scored: Iterable[str], keys: Iterable[str]) -> list[dict]:
    """``coverage["not_computable"]``: ``{"clip", "metrics", "reason"}`` for each scored item of ``missing``
    (item -> why its partner's ground truth is missing), in ``missing``'s order; ``keys`` are the suite's
    partner-based keys."""
    scored, keys = set(scored), list(keys)
    return [{"clip": stem, "metrics": keys, "reason": reason} for stem, reason in missing.items() if stem in scored]


def notes(entries: list[dict], n_scored: int, headers: str, aggregate: str = "means") -> list[str]:
    """The report note for :func:`not_computable`'s ``entries`` (none when empty): how many of the
    ``n_scored`` items lack ``headers`` (e.g. "P-FD, rPCC") and why, the first three named; those columns
    are ``aggregate`` (e.g. "means") over the other items, or NaN when no scored item has its partner."""
    if not entries:
        return []
    shown = ", ".join(e["clip"] for e in entries[:3]) + (", …" if len(entries) > 3 else "")
    over = ("not computable for any scored clip (NaN)" if len(entries) == n_scored
            else f"{aggregate} over the other clips")
    return [f"{headers} not computable for {len(entries)} of {n_scored} clips: the partner's ground truth is "
            f"missing ({shown}; listed under coverage.not_computable); every other metric is scored; "
            f"{headers}: {over}"]
