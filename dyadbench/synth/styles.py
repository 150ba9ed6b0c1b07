"""Persistent per-person styles and per-split conversation statistics of the synthetic corpus.

Identities come from two style pools: the *seen* pool (train and test draw their people from it) and the
*unseen* pool (ood only), whose style ranges are shifted (faster speech, later and larger nods, more
smiling, higher voices, livelier heads). The ood split also has different turn statistics: shorter turns,
shorter phrases, more overlap and more back-channels. Pools and the "world" (expression bases shared by
everyone) are deterministic functions of the seed and the generator version.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from functools import lru_cache

import numpy as np

from dyadbench.errors import ConfigError
from dyadbench.seeding import rng as seeded_rng

GENERATOR_VERSION = 1
EXP_DIM = 50
AFFECT_DIM = 4  # affect latent: 0 smile, 1 brow raise, 2-3 other slow expression modes


@dataclass(frozen=True)
class TurnStats:
    """Conversation statistics of a split (seconds)."""

    duration_mean_s: float  # clip length: log-normal with this mean
    turn_mean_s: float  # floor-holding turn length (gamma, shape 2), scaled by the holder's style
    phrase_mean_s: float  # inter-pausal unit length inside a turn (gamma, shape 3)
    pause_mean_s: float  # silent pause between phrases of a turn (gamma, shape 2)
    gap_mean_s: float  # next turn start minus current turn end (normal); negative = overlap
    gap_std_s: float
    backchannel_prob: float  # chance a listener vocalises after a partner's phrase end
    interjection_rate: float  # listener vocalisations per second of partner speech (overlapping)


SPLIT_STATS = {
    "seen": TurnStats(duration_mean_s=31.0, turn_mean_s=14.0, phrase_mean_s=2.4, pause_mean_s=0.45,
                      gap_mean_s=-0.2, gap_std_s=0.7, backchannel_prob=0.35, interjection_rate=0.06),
    "unseen": TurnStats(duration_mean_s=31.0, turn_mean_s=6.0, phrase_mean_s=1.6, pause_mean_s=0.35,
                        gap_mean_s=-0.5, gap_std_s=0.7, backchannel_prob=0.55, interjection_rate=0.12),
}
SPLIT_POOL = {"train": "seen", "test": "seen", "val": "seen", "ood": "unseen"}
POOL_SIZE = {"seen": 240, "unseen": 120}

# style ranges (uniform low, high) per pool; the unseen ranges are shifted, mostly outside the seen ones
STYLE_RANGES = {
    "seen": {
        "syllable_rate": (4.0, 5.0), "f0_base": (95.0, 210.0), "f0_accent": (0.15, 0.3),
        "loudness": (0.12, 0.25), "timbre_tilt": (0.8, 1.4),
        "jaw_rest": (0.0, 0.05), "jaw_gain": (0.07, 0.12), "artic_gain": (0.9, 1.3),
        "head_speak_amp": (0.04, 0.07), "idle_head_std": (0.01, 0.02),
        "nod_amp": (0.04, 0.07), "nod_prob": (0.6, 0.9), "nod_lag_s": (0.25, 0.4),
        "smile_amp": (0.8, 1.4), "smile_prob": (0.4, 0.7), "smile_lag_s": (0.4, 0.6),
        "mirror_gain": (0.35, 0.6), "blink_rate": (0.2, 0.4), "idle_exp_std": (0.12, 0.2),
        "affect_std": (0.4, 0.7), "backchannel_tendency": (0.6, 1.4), "turn_factor": (0.7, 1.3),
    },
    "unseen": {
        "syllable_rate": (5.0, 6.0), "f0_base": (150.0, 260.0), "f0_accent": (0.25, 0.4),
        "loudness": (0.15, 0.3), "timbre_tilt": (1.3, 1.8),
        "jaw_rest": (0.02, 0.07), "jaw_gain": (0.1, 0.15), "artic_gain": (1.1, 1.5),
        "head_speak_amp": (0.06, 0.1), "idle_head_std": (0.015, 0.03),
        "nod_amp": (0.06, 0.09), "nod_prob": (0.7, 0.95), "nod_lag_s": (0.4, 0.55),
        "smile_amp": (1.2, 1.8), "smile_prob": (0.6, 0.9), "smile_lag_s": (0.55, 0.75),
        "mirror_gain": (0.5, 0.75), "blink_rate": (0.35, 0.55), "idle_exp_std": (0.15, 0.25),
        "affect_std": (0.5, 0.8), "backchannel_tendency": (1.0, 1.8), "turn_factor": (0.6, 1.0),
    },
}


@dataclass(frozen=True)
class Style:
    """One person's persistent style (see STYLE_RANGES for the meaning and units of each field)."""

    identity: str
    syllable_rate: float  # Hz
    f0_base: float  # Hz
    f0_accent: float  # relative pitch rise on emphasised syllables
    loudness: float  # peak amplitude of voiced speech (full scale 1)
    timbre_tilt: float  # harmonic roll-off exponent of the voice
    jaw_rest: float  # rad
    jaw_gain: float  # rad per unit speech envelope
    artic_gain: float  # articulation expression per unit envelope
    head_speak_amp: float  # rad per unit relative pitch deviation while speaking
    idle_head_std: float  # rad
    nod_amp: float  # rad
    nod_prob: float
    nod_lag_s: float
    smile_amp: float
    smile_prob: float
    smile_lag_s: float
    mirror_gain: float
    blink_rate: float  # per second
    idle_exp_std: float
    affect_std: float
    backchannel_tendency: float
    turn_factor: float
    exp_offset: tuple[float, ...]  # (50,) identity expression offset
    head_mean: tuple[float, float, float]  # rad, camera-relative head rotation

    def as_dict(self) -> dict:
        return asdict(self)


@dataclass(frozen=True)
class World:
    """Expression bases shared by every person (fixed per generator version)."""

    dim_scale: np.ndarray  # (50,) typical magnitude per expression dim (larger for early dims)
    population_mean: np.ndarray  # (50,)
    artic: np.ndarray  # (2, 50): mouth articulation for open ("a") and spread ("i") vowels
    affect: np.ndarray  # (AFFECT_DIM, 50)
    blink: np.ndarray  # (50,)


def _unit_rows(m: np.ndarray) -> np.ndarray:
    return m / np.linalg.norm(m, axis=-1, keepdims=True)


@lru_cache(maxsize=4)
def world(version: int = GENERATOR_VERSION) -> World:
    r = seeded_rng("dyadbench-synth-world", version)
    d = np.arange(EXP_DIM)
    dim_scale = 0.45 + 0.4 * np.exp(-d / 8.0)
    population_mean = r.normal(0.0, 1.0, EXP_DIM) * (0.6 + 0.6 * np.exp(-d / 15.0))

    def basis(rows: int, focus: float) -> np.ndarray:
        raw = r.standard_normal((rows, EXP_DIM)) * (0.3 + np.exp(-d / focus))[None, :]
        return _unit_rows(raw) * np.sqrt(EXP_DIM) * dim_scale[None, :] / np.sqrt(np.mean(dim_scale ** 2))

    return World(dim_scale=dim_scale, population_mean=population_mean, artic=basis(2, 8.0) * 0.55,
                 affect=basis(AFFECT_DIM, 20.0) * 0.45, blink=basis(1, 30.0)[0] * 0.5)


def _draw_style(r: np.random.Generator, identity: str, ranges: dict, w: World) -> Style:
    values = {name: float(r.uniform(lo, hi)) for name, (lo, hi) in ranges.items()}
    offset = w.population_mean + r.normal(0.0, 0.3, EXP_DIM) * w.dim_scale
    head_mean = np.array([0.1, 0.12, 0.0]) + r.normal(0.0, 1.0, 3) * np.array([0.03, 0.04, 0.02])
    return Style(identity=identity, exp_offset=tuple(float(x) for x in offset),
                 head_mean=tuple(float(x) for x in head_mean), **values)


@lru_cache(maxsize=8)
def style_pool(pool: str, seed: int = 0) -> tuple[Style, ...]:
    """The identities of a pool ("seen" or "unseen"), deterministic in (seed, pool, version)."""
    if pool not in STYLE_RANGES:
        raise ConfigError(f"unknown style pool {pool!r} (known: {', '.join(STYLE_RANGES)})")
    r = seeded_rng(seed, "style-pool", pool, GENERATOR_VERSION)
    w = world()
    return tuple(_draw_style(r, f"synth-{pool}-{k:04d}", STYLE_RANGES[pool], w) for k in range(POOL_SIZE[pool]))


def split_pool(split: str) -> str:
    """The pool a split draws its people and turn statistics from."""
    try:
        return SPLIT_POOL[split]
    except KeyError:
        raise ConfigError(f"unknown synthetic split {split!r} (known: {', '.join(SPLIT_POOL)})") from None
