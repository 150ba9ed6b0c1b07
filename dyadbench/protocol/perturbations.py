"""Input perturbations (the robustness protocol): tracking and microphone failures applied on the fly.

A :class:`Perturbation` corrupts one input stream of what a model receives, never the ground truth the
predictions are scored against and never a file on disk: the partner's motion (``partner-motion``: ``drop``
holds the last frame, ``gaussian`` / ``laplace`` / ``uniform`` add noise), the partner's speech
(``partner-speech``) or the agent's own speech (``agent-speech``): ``silence`` zeroes samples, ``noise``
adds white Gaussian noise at ``snr_db``. Each acts inside a burst mask (:func:`burst_mask`) of expected
occupancy ``occupancy`` and mean burst length ``burst_s`` seconds. Written ``TARGET:KIND:OCCUPANCY[:BURST_S
[:SNR_DB]]`` (:func:`parse`), e.g. ``partner-motion:drop:0.3`` or ``agent-speech:silence:1:4``.

Facts kept from TIMAR's released perturbation script (``shared/specs/robustness.md``):

- hold-last drop: a masked frame takes the previous (already filled) frame; frame 0 is never replaced;
- motion noise: i.i.d. on all dimensions of masked frames, one scale sigma for every dimension: the mean over
  the dimensions of the train split's per-dimension standard deviation, rounded to 3 decimals
  (:mod:`dyadbench.protocol.noise_scale`); gaussian std sigma, laplace scale b = sigma, uniform on [-sigma, +sigma];
- speech noise: ``noise_std = sqrt(mean(x^2) / 10^(snr/10))`` over the whole signal x, added on masked samples;
- perturbations of one stream compose: noise first, then drop / silence.

The corruption is causal except for two recorded facts of the release: the speech-noise level is set by the
whole clip's power, and under ``speech_norm = clip`` the waveform statistics are those of the corrupted clip
(the release normalises the corrupted files it wrote).

Where dyadbench departs from the script:

- **Occupancy is exact.** The script starts a burst at each free position with probability
  ``prob / mean_len``; a renewal argument gives an expected occupied fraction of
  ``m / (m + m/prob - 1)`` ~ ``prob / (1 + prob)`` (0.7 occupies ~41 %). Here a burst starts with probability
  ``p = q / (q + m (1 - q))`` so that the stationary occupied fraction m / (m + (1 - p)/p) equals the requested
  ``q``; burst lengths are geometric with mean ``m = max(1, burst_s * rate)``.
- **Seeds per clip and participant.** Each mask and noise draw uses its own generator seeded by
  :func:`perturbation_seed` (run seed, clip, participant, signal, kind), so a clip's perturbation does not
  depend on the order clips are run in, and the partner-speech and agent-speech perturbations of one
  person's microphone coincide.
- Speech given only as dataset speech features (Learning2Listen's mel rows) is refused: the release defines
  silence and SNR on waveforms, and a mel row's silence depends on its unknown floor and scaling.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from dyadbench.datasets.base import DyadicClip, Participant
from dyadbench.errors import ConfigError, InputError
from dyadbench.seeding import derive_seed

MOTION_KINDS = ("drop", "gaussian", "laplace", "uniform")
SPEECH_KINDS = ("silence", "noise")
KINDS = {"partner-motion": MOTION_KINDS, "partner-speech": SPEECH_KINDS, "agent-speech": SPEECH_KINDS}
DEFAULT_BURST_S = 1.0  # the paper's sweeps
DEFAULT_SNR_DB = 60.0  # the release's default
#: Kinds that hold or zero the signal; they are applied after the noise kinds.
MASKING = ("drop", "silence")


@dataclass(frozen=True)
class Perturbation:
    """One corrupted input stream (see the module docstring)."""

    target: str
    kind: str
    occupancy: float
    burst_s: float = DEFAULT_BURST_S
    snr_db: float = DEFAULT_SNR_DB

    def __post_init__(self) -> None:
        if self.target not in KINDS:
            raise ConfigError(f"perturbation target must be one of {', '.join(KINDS)}, got {self.target!r}")
        if self.kind not in KINDS[self.target]:
            raise ConfigError(f"{self.target} perturbations are {', '.join(KINDS[self.target])}, got {self.kind!r}")
        for name, low in (("occupancy", 0.0), ("burst_s", 0.0), ("snr_db", -math.inf)):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
                raise ConfigError(f"perturbation {name} must be a finite number, got {value!r}")
            object.__setattr__(self, name, float(value))
        if not 0 < self.occupancy <= 1:
            raise ConfigError(f"perturbation occupancy must be in (0, 1], got {self.occupancy:g}")
        if not self.burst_s > 0:
            raise ConfigError(f"perturbation burst length must be > 0 seconds, got {self.burst_s:g}")

    @property
    def signal(self) -> str:
        return "motion" if self.target == "partner-motion" else "speech"

    @property
    def family(self) -> str:
        """The perturbation without its level, e.g. ``partner-speech noise 60dB``."""
        return f"{self.target} {self.kind}" + (f" {self.snr_db:g}dB" if self.kind == "noise" else "")

    def text(self) -> str:
        """The canonical ``TARGET:KIND:OCCUPANCY:BURST_S[:SNR_DB]`` (what results record; :func:`parse` reads it)."""
        snr = f":{self.snr_db:g}" if self.kind == "noise" else ""
        return f"{self.target}:{self.kind}:{self.occupancy:g}:{self.burst_s:g}{snr}"

    def label(self) -> str:
        """File-name part, e.g. ``partner-motion-drop0.3`` (``-b4s`` for a burst other than 1 s, ``-snr30``)."""
        burst = f"-b{self.burst_s:g}s" if self.burst_s != DEFAULT_BURST_S else ""
        snr = f"-snr{self.snr_db:g}" if self.kind == "noise" and self.snr_db != DEFAULT_SNR_DB else ""
        return f"{self.target}-{self.kind}{self.occupancy:g}{burst}{snr}"


def parse(text: str) -> Perturbation:
    """``TARGET:KIND:OCCUPANCY[:BURST_S[:SNR_DB]]`` -> :class:`Perturbation` (ConfigError naming the text)."""
    parts = [p.strip() for p in str(text).split(":")]
    if not 3 <= len(parts) <= 5 or (len(parts) == 5 and parts[1] != "noise"):
        raise ConfigError(f"perturbation {text!r}: expected TARGET:KIND:OCCUPANCY[:BURST_S[:SNR_DB]] "
                          f"(SNR only for noise), e.g. partner-motion:drop:0.3 or partner-speech:noise:0.5:1:60")
    try:
        numbers = [float(p) for p in parts[2:]]
    except ValueError:
        raise ConfigError(f"perturbation {text!r}: occupancy, burst seconds and SNR must be numbers") from None
    return Perturbation(parts[0], parts[1], *numbers)


def parse_all(text: str) -> tuple[Perturbation, ...]:
    """The ``+``-joined texts a result records (``""``: none)."""
    return tuple(parse(t) for t in text.split("+")) if text else ()


def describe(perturbations: tuple[Perturbation, ...]) -> str:
    """The ``+``-joined canonical texts (``""`` for none): what a result and its configuration record."""
    return "+".join(p.text() for p in perturbations)


def variant_part(perturbations: tuple[Perturbation, ...], noise_scale: float | None) -> str:
    """The result-file name part of a perturbed run (``""`` for none); ``sigma<x>`` when the motion-noise
    scale was given rather than taken from the train split."""
    parts = [p.label() for p in perturbations]
    if noise_scale is not None and needs_noise_scale(perturbations):
        parts.append(f"sigma{noise_scale:g}")
    return "+".join(parts)


def needs_noise_scale(perturbations: tuple[Perturbation, ...]) -> bool:
    return any(p.signal == "motion" and p.kind not in MASKING for p in perturbations)


def perturbation_seed(seed: int, clip_id: str, participant: str, signal: str, kind: str) -> int:
    """The seed of one participant's perturbation of one signal in one clip (order-independent)."""
    return derive_seed(seed, "perturbation", clip_id, participant, signal, kind)


def burst_start_probability(occupancy: float, mean_len: float) -> float:
    """p with stationary occupied fraction m / (m + (1 - p) / p) = ``occupancy`` (1 when it is 1)."""
    return occupancy / (occupancy + mean_len * (1.0 - occupancy))


def burst_mask(length: int, occupancy: float, mean_len: float, rng: np.random.Generator) -> np.ndarray:
    """A boolean mask of ``length`` positions: alternating free gaps (geometric, a burst starts at each
    free position with :func:`burst_start_probability`) and bursts (geometric lengths >= 1 with mean
    ``mean_len``), starting free. Expected occupied fraction ``occupancy`` (exactly, up to the start)."""
    mask = np.zeros(length, dtype=bool)
    if occupancy >= 1:
        mask[:] = True
        return mask
    mean_len = max(1.0, float(mean_len))
    p_start, p_end = burst_start_probability(occupancy, mean_len), 1.0 / mean_len
    pos = 0
    while pos < length:
        pos += int(rng.geometric(p_start)) - 1  # free positions before the next start
        stop = pos + int(rng.geometric(p_end))
        mask[pos:stop] = True
        pos = stop
    return mask


def hold_last(x: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """Masked rows replaced by the last unmasked row before them (frame 0 is never replaced)."""
    keep = ~mask
    keep[0] = True
    source = np.maximum.accumulate(np.where(keep, np.arange(len(x)), 0))
    return x[source]


def speech_noise_std(x: np.ndarray, snr_db: float) -> float:
    """``sqrt(mean(x^2) / 10^(snr/10))`` over the whole signal (the release's noise level)."""
    power = float(np.mean(np.square(x, dtype=np.float64))) if x.size else 0.0
    return math.sqrt(power / 10 ** (snr_db / 10))


def _noise(kind: str, scale: float, shape: tuple[int, ...], rng: np.random.Generator) -> np.ndarray:
    if kind == "laplace":
        return rng.laplace(0.0, scale, shape)
    if kind == "uniform":
        return rng.uniform(-scale, scale, shape)
    return rng.normal(0.0, scale, shape)


def perturb_signal(x: np.ndarray, perturbations: list[Perturbation], rate: float, *, seed: int, clip_id: str,
                   participant: str, noise_scale: float | None) -> np.ndarray:
    """``x`` (motion (T, D) or speech (S,)) with ``perturbations`` of one signal applied, noise kinds first."""
    out = np.array(x, dtype=np.float32, copy=True)
    if out.shape[0] == 0:
        return out
    for p in sorted(perturbations, key=lambda p: p.kind in MASKING):
        rng = np.random.default_rng(perturbation_seed(seed, clip_id, participant, p.signal, p.kind))
        mask = burst_mask(out.shape[0], p.occupancy, p.burst_s * rate, rng)
        if p.kind in MASKING:
            out = hold_last(out, mask) if p.kind == "drop" else np.where(mask, 0, out).astype(np.float32)
            continue
        scale = noise_scale if p.signal == "motion" else speech_noise_std(x, p.snr_db)
        out[mask] += _noise(p.kind, scale, (int(mask.sum()),) + out.shape[1:], rng).astype(np.float32)
    return out


def perturbed_inputs(clip: DyadicClip, agent: str, perturbations: tuple[Perturbation, ...], seed: int,
                     noise_scale: float | None) -> DyadicClip:
    """The clip a model receives for the direction with ``agent`` generated: the partner's motion and speech
    and the agent's speech perturbed; the agent's motion (ground truth, oracles' input) untouched."""
    if not perturbations:
        return clip
    if needs_noise_scale(perturbations) and noise_scale is None:
        raise ConfigError("motion noise needs its scale (ProtocolConfig.noise_scale)")
    partner = clip.partner_of(agent)
    targets = {clip.participant(agent).name: {"agent-speech"},
               **({partner.name: {"partner-motion", "partner-speech"}} if partner else {})}
    people = []
    for person in clip.participants:
        mine = [p for p in perturbations if p.target in targets[person.name]]
        people.append(_perturb_person(clip, person, mine, seed, noise_scale) if mine else person)
    return replace(clip, participants=tuple(people))


def _perturb_person(clip: DyadicClip, person: Participant, mine: list[Perturbation], seed: int,
                    noise_scale: float | None) -> Participant:
    speech = [p for p in mine if p.signal == "speech"]
    if speech and person.speech_features is not None:
        raise InputError(f"{clip.clip_id}_{person.name}",
                         "speech perturbations act on waveforms; this dataset ships the speech as feature rows "
                         "(e.g. Learning2Listen's mel spectrogram), for which silence and SNR are not defined")
    where = {"seed": seed, "clip_id": clip.clip_id, "participant": person.name, "noise_scale": noise_scale}
    motion = [p for p in mine if p.signal == "motion"]
    return replace(person,
                   motion=perturb_signal(person.motion, motion, clip.fps, **where) if motion else person.motion,
                   audio=perturb_signal(person.audio, speech, clip.sample_rate, **where) if speech else person.audio)
