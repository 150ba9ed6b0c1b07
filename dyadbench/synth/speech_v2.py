"""Speech of the v2 synthetic corpus: v1's voice (:mod:`dyadbench.synth.speech`) with a prosody that follows
the shared mood m(t) (:func:`dyadbench.synth.conversation.shared_mood`).

Per unit of mood (vocal arousal cues, Scherer 2003; Banse & Scherer 1996):

- pitch level: f0 x (1 + 0.06 m);
- pitch range: the contour's excursions (declination, accents, vibrato) raised to the power 1 + 0.3 m,
  f0 = f0_base x level x (f0_v1 / f0_base) ^ range;
- loudness: the syllable envelope (and consonant bursts) x (1 + 0.15 m).

Scales are clipped to stay positive. With m = 0 everywhere the signals equal v1's for the same draws.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from dyadbench.features.activity import segments_mask
from dyadbench.synth import speech
from dyadbench.synth.signals import block_mean
from dyadbench.synth.styles import Style
from dyadbench.synth.timeline import Track

F0_LEVEL, F0_RANGE, LOUDNESS = 0.06, 0.3, 0.15  # per unit mood


@dataclass(frozen=True)
class Prosody:
    """Frame-rate multipliers of a speaker's voice: (T,) each."""

    level: np.ndarray  # f0 level
    range: np.ndarray  # exponent on the relative pitch contour
    loudness: np.ndarray  # envelope

    @classmethod
    def from_mood(cls, mood: np.ndarray) -> Prosody:
        return cls(level=np.maximum(0.5, 1.0 + F0_LEVEL * mood), range=np.maximum(0.3, 1.0 + F0_RANGE * mood),
                   loudness=np.maximum(0.4, 1.0 + LOUDNESS * mood))


def speech_signals(r: np.random.Generator, track: Track, style: Style, n_frames: int, fps: float,
                   sample_rate: int, prosody: Prosody) -> speech.SpeechSignals:
    """Like :func:`dyadbench.synth.speech.speech_signals`, with ``prosody`` applied on the fine grid.

    ``pitch`` is f0 / f0_base - 1 while voiced, so it carries the mood's pitch level too.
    """
    per_frame = int(round(speech.FINE_RATE / fps))
    n_fine = n_frames * per_frame
    env, f0, vowel, burst = speech._fine_signals(track, style, n_fine)
    level, span, loud = (np.repeat(x, per_frame) for x in (prosody.level, prosody.range, prosody.loudness))
    f0 = style.f0_base * level * (f0 / style.f0_base) ** span
    env, burst = env * loud, burst * loud
    hop = int(round(sample_rate / fps))
    audio = speech._synthesise(r, style, env, f0, vowel, burst, track.phrases, n_frames * hop, sample_rate)
    env_frame = block_mean(env, per_frame)
    pitch = block_mean(np.where(env > 0, f0 / style.f0_base - 1.0, 0.0), per_frame)
    vowel_frame = block_mean(vowel * env, per_frame) / np.maximum(env_frame, 1e-9)
    return speech.SpeechSignals(speaking=segments_mask(track.phrases, n_frames, fps), envelope=env_frame,
                                vowel=np.where(env_frame > 0, vowel_frame, 0.0), pitch=pitch, audio=audio)
