"""Listener nods of the v2 synthetic corpus whose probability depends on the conversation's history.

A listener may nod at each partner event it hears while silent (a phrase end or an emphasised syllable,
as in v1). In v2 the chance of a nod is

    p = min(0.95, nod_prob x f_engage(t) x f_excite(t))

- f_engage = 0.4 + 0.6 e(t), with e the listener's engagement (:func:`dyadbench.synth.conversation.engagement`:
  back-channels grow likelier the longer the partner has held the floor; Ward & Tsukahara 2000);
- f_excite = clip(1 + 0.25 (h - 2), 0.3, 1.6) with h = sum over the listener's own earlier nods of
  exp(-dt / 6 s) + 0.5 x the same sum over the partner's nods: nods come in runs and are answered with
  nods (Hadar, Steiner & Rose 1985; Maynard 1987), a self- and mutually-exciting (Hawkes-like) process.

Either factor is 1 when its mechanism is off. One uniform draw per candidate event is made whatever the
switches, so switching a mechanism off changes no other random choice.
"""

from __future__ import annotations

import numpy as np

NOD_MEMORY_S = 6.0
MUTUAL_WEIGHT = 0.5  # weight of the partner's nods in the listener's excitation
EXCITE_GAIN, EXCITE_REF, EXCITE_RANGE = 0.25, 2.0, (0.3, 1.6)
ENGAGE_FLOOR = 0.4
MAX_PROB = 0.95


def engage_factor(engagement: np.ndarray, on: bool) -> np.ndarray:
    """f_engage(t) = 0.4 + 0.6 e(t) (ones when the mechanism is off)."""
    return ENGAGE_FLOOR + (1.0 - ENGAGE_FLOOR) * engagement if on else np.ones_like(engagement)


def excitation(at: int, own: list[int], partner: list[int], fps: float) -> float:
    """h: the listener's own earlier nods and the partner's, exponentially forgotten (NOD_MEMORY_S)."""
    tau = NOD_MEMORY_S * fps
    return (float(np.exp(-(at - np.asarray(own, dtype=float)) / tau).sum())
            + MUTUAL_WEIGHT * float(np.exp(-(at - np.asarray(partner, dtype=float)) / tau).sum()))


def nod_frames(r: np.random.Generator, candidates: tuple[np.ndarray, np.ndarray], nod_prob: tuple[float, float],
               engage: tuple[np.ndarray, np.ndarray], fps: float, excite: bool) -> tuple[np.ndarray, np.ndarray]:
    """Frames of the partner events each listener nods at, drawn in time order (see the module docstring).

    ``candidates[p]``: frames of the events listener ``p`` hears while silent; ``engage[p]``: its
    f_engage per frame.
    """
    who = np.concatenate([np.full(len(c), p) for p, c in enumerate(candidates)]).astype(np.int64)
    at = np.concatenate(candidates).astype(np.int64)
    order = np.lexsort((who, at))
    draws = r.random(len(at))
    nods: tuple[list[int], list[int]] = ([], [])
    for k in order:
        p, f = int(who[k]), int(at[k])
        boost = 1.0
        if excite:
            h = excitation(f, nods[p], nods[1 - p], fps)
            boost = float(np.clip(1.0 + EXCITE_GAIN * (h - EXCITE_REF), *EXCITE_RANGE))
        if draws[k] < min(MAX_PROB, nod_prob[p] * engage[p][f] * boost):
            nods[p].append(f)
    return np.asarray(nods[0], dtype=np.int64), np.asarray(nods[1], dtype=np.int64)
