"""Slow conversational state of the v2 synthetic corpus: shared mood, entrainment and listener engagement.

Each function returns frame-rate (25 fps) arrays; :class:`Dynamics` switches every mechanism on or off
(off = the mechanism is removed: a neutral state of zeros or unit gains). Their time constants, sources
and what they drive are tabulated in :mod:`dyadbench.synth.corpus_v2`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from dyadbench.synth.signals import ou_process

MOOD_TAU_S = 20.0  # shared mood: OU time constant
CONVERGE_TAU_S = 30.0  # entrainment: c(t) = 1 - exp(-t / 30 s)
CONVERGE_SHARE = 0.6  # fraction of the energy gap to the partner closed as c -> 1
ENGAGE_RISE_S, ENGAGE_DECAY_S = 5.0, 2.0  # listener engagement while the partner holds the floor / after


@dataclass(frozen=True)
class Dynamics:
    """Which long-range mechanisms of the v2 generator are on (all by default)."""

    mood: bool = True  # shared slow mood -> expression baselines and prosody of both people
    contagion: bool = True  # expression and head-motion energy converge toward the partner's
    engagement: bool = True  # listener engagement grows with how long the partner has held the floor
    nod_excitation: bool = True  # nods excite later nods (own and the partner's)

    def as_dict(self) -> dict:
        return {k: bool(getattr(self, k)) for k in self.__dataclass_fields__}


def shared_mood(r: np.random.Generator, n: int, fps: float, on: bool) -> np.ndarray:
    """(n,) unit-variance OU mood shared by both people (tau ``MOOD_TAU_S``); zeros when off.

    The draw is made either way, so switching the mood off changes no other random choice.
    """
    m = ou_process(r, n, MOOD_TAU_S * fps, 1.0)[:, 0]
    return m if on else np.zeros(n)


def convergence(n: int, fps: float, on: bool) -> np.ndarray:
    """(n,) entrainment progress c(t) = 1 - exp(-t / CONVERGE_TAU_S); zeros when off."""
    t = np.arange(n) / fps
    return 1.0 - np.exp(-t / CONVERGE_TAU_S) if on else np.zeros(n)


def energy_gain(own: float, partner: float, progress: np.ndarray) -> np.ndarray:
    """(n,) gain g(t) = 1 + CONVERGE_SHARE c(t) (partner / own - 1) on a person's motion energy: 1 at the
    start, moving the person's energy ``own`` toward the partner's ``partner`` as c(t) grows."""
    return 1.0 + CONVERGE_SHARE * progress * (partner / own - 1.0)


def floor_mask(turns: tuple[tuple[int, float, float], ...], holder: int, n: int, fps: float) -> np.ndarray:
    """(n,) bool: frames inside one of ``holder``'s floor-holding turns."""
    t = (np.arange(n) + 0.5) / fps
    out = np.zeros(n, dtype=bool)
    for who, start, end in turns:
        if who == holder:
            out |= (t >= start) & (t < end)
    return out


def engagement(partner_floor: np.ndarray, fps: float, on: bool) -> np.ndarray:
    """(n,) listener engagement in [0, 1]: a one-pole follower of "the partner holds the floor" that rises
    with time constant ENGAGE_RISE_S while the partner talks and decays with ENGAGE_DECAY_S after, i.e.
    e = 1 - exp(-elapsed / 4 s) from the start of a partner's turn; zeros when off."""
    n = len(partner_floor)
    e = np.zeros(n)
    if not on or n == 0:
        return e
    edges = np.flatnonzero(np.diff(partner_floor.astype(np.int8))) + 1
    level = 0.0
    for a, b in zip(np.r_[0, edges], np.r_[edges, n]):
        target, tau = (1.0, ENGAGE_RISE_S) if partner_floor[a] else (0.0, ENGAGE_DECAY_S)
        k = np.arange(1, b - a + 1)
        e[a:b] = target + (level - target) * np.exp(-k / (tau * fps))
        level = e[b - 1]
    return e
