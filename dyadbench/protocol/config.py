"""Parameters of the progressive-context streaming protocol, validated once and recorded in results.

- ``turn_seconds``: length of one turn (1 s = 25 frames at 25 fps, 16,000 samples at 16 kHz); it must
  cover a whole number of motion frames and audio samples.
- ``context``: n, the number of history turns handed to the model with the current one (0 = none).
- ``tail``: frames after the last whole turn: ``truncate`` (not predicted; the published TIMAR
  numbers) or ``pad-last`` (repeat the last predicted frame; the TIMAR paper text).
- ``history_agent``: ``masked`` (default, TIMAR's published runs: the model never sees agent motion of
  history turns) or ``outputs`` (the model gets its own earlier outputs for the history turns).
- ``seed``: run seed; each stream's seed is derived from (seed, clip, agent).
- ``speech_norm``: statistics that models normalising waveforms (wav2vec 2.0 front ends) use:
  ``window`` (default, causal: the audio handed over with each turn) or ``clip`` (the whole clip's
  waveform mean and variance, handed over in the stream context, as the released TIMAR and DualTalk
  evaluations normalise each clip; it reads future audio, so such runs are not strictly causal).
- ``perturbations``: input perturbations of the robustness protocol
  (:mod:`dyadbench.protocol.perturbations`), at most one per target and kind; ``noise_scale``: the motion
  noise scale sigma (None: taken from the train split when a motion-noise perturbation needs it,
  :mod:`dyadbench.protocol.noise_scale`).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

from dyadbench.errors import ConfigError
from dyadbench.protocol.perturbations import Perturbation

TAILS = ("truncate", "pad-last")
HISTORY_AGENT = ("masked", "outputs")
SPEECH_NORMS = ("window", "clip")
_INTEGER_TOLERANCE = 1e-9


@dataclass(frozen=True)
class ProtocolConfig:
    """Validated protocol parameters (see the module docstring)."""

    turn_seconds: float = 1.0
    context: int = 7
    tail: str = "truncate"
    history_agent: str = "masked"
    seed: int = 0
    speech_norm: str = "window"
    perturbations: tuple[Perturbation, ...] = ()
    noise_scale: float | None = None

    def __post_init__(self) -> None:
        if isinstance(self.context, bool) or not isinstance(self.context, int) or self.context < 0:
            raise ConfigError(f"context must be a whole number of history turns >= 0, got {self.context!r}")
        try:
            seconds = float(self.turn_seconds)
        except (TypeError, ValueError):
            raise ConfigError(f"turn_seconds must be a number, got {self.turn_seconds!r}") from None
        if not seconds > 0 or seconds != seconds or seconds == float("inf"):
            raise ConfigError(f"turn_seconds must be a positive finite number, got {self.turn_seconds!r}")
        object.__setattr__(self, "turn_seconds", seconds)
        if self.tail not in TAILS:
            raise ConfigError(f"tail must be one of {', '.join(TAILS)}, got {self.tail!r}")
        if self.history_agent not in HISTORY_AGENT:
            raise ConfigError(f"history_agent must be one of {', '.join(HISTORY_AGENT)}, "
                              f"got {self.history_agent!r}")
        if self.speech_norm not in SPEECH_NORMS:
            raise ConfigError(f"speech_norm must be one of {', '.join(SPEECH_NORMS)}, got {self.speech_norm!r}")
        if isinstance(self.seed, bool) or not isinstance(self.seed, int):
            raise ConfigError(f"seed must be an integer, got {self.seed!r}")
        _check_perturbations(tuple(self.perturbations), self.noise_scale)
        object.__setattr__(self, "perturbations", tuple(self.perturbations))

    def frames_per_turn(self, fps: float) -> int:
        """Motion frames in one turn at ``fps``; a ConfigError unless that is a whole number >= 1."""
        return _whole(self.turn_seconds * fps, f"turn_seconds={self.turn_seconds} at {fps} fps", "frames")

    def samples_per_turn(self, sample_rate: int) -> int:
        """Audio samples in one turn at ``sample_rate``; a ConfigError unless that is a whole number >= 1."""
        return _whole(self.turn_seconds * sample_rate,
                      f"turn_seconds={self.turn_seconds} at {sample_rate} Hz", "samples")

    def to_dict(self) -> dict:
        return asdict(self)


def _check_perturbations(perturbations: tuple, noise_scale: float | None) -> None:
    """Perturbation objects, at most one per (target, kind); a positive finite noise scale or None."""
    if not all(isinstance(p, Perturbation) for p in perturbations):
        raise ConfigError(f"perturbations must be Perturbation objects, got {perturbations!r}")
    kinds = [(p.target, p.kind) for p in perturbations]
    if len(set(kinds)) != len(kinds):
        raise ConfigError("at most one perturbation per target and kind (they would share their bursts)")
    if noise_scale is not None and not (isinstance(noise_scale, (int, float)) and not isinstance(noise_scale, bool)
                                        and 0 < noise_scale < float("inf")):
        raise ConfigError(f"noise_scale must be a positive finite number, got {noise_scale!r}")


def _whole(value: float, what: str, unit: str) -> int:
    count = round(value)
    if abs(value - count) > _INTEGER_TOLERANCE * max(1.0, abs(value)) or count < 1:
        raise ConfigError(f"{what} is {value:g} {unit} per turn; a turn must hold a whole number >= 1 of {unit}")
    return int(count)


_DEFAULT = ProtocolConfig()
DEFAULT_CFG_SCALE = 1.0  # guidance off, as in TIMAR's published runs


def variant_label(*, turn_seconds: float = _DEFAULT.turn_seconds, tail: str = _DEFAULT.tail,
                  history_agent: str = _DEFAULT.history_agent, cfg_scale: float = DEFAULT_CFG_SCALE,
                  seed: int = _DEFAULT.seed, speech_norm: str = _DEFAULT.speech_norm) -> str:
    """Short name of a run's settings that differ from the default protocol ("" when none do).

    Used to keep runs of one model apart that differ only in these settings: the sweep's result file
    names (``<model>@<label>.json``) and the model labels of the wide leaderboards, e.g.
    ``cfg2+seed1`` for guidance scale 2 with run seed 1 (``speech-clip`` for ``speech_norm = clip``).
    Context is not part of it (it has its own folder and column).
    """
    parts = []
    if turn_seconds != _DEFAULT.turn_seconds:
        parts.append(f"turn{turn_seconds:g}s")
    if tail != _DEFAULT.tail:
        parts.append(f"tail-{tail}")
    if history_agent != _DEFAULT.history_agent:
        parts.append(f"history-{history_agent}")
    if cfg_scale != DEFAULT_CFG_SCALE:
        parts.append(f"cfg{cfg_scale:g}")
    if seed != _DEFAULT.seed:
        parts.append(f"seed{seed}")
    if speech_norm != _DEFAULT.speech_norm:
        parts.append(f"speech-{speech_norm}")
    return "+".join(parts)
