"""Features of what the streaming protocol shows a model: per frame of the current turn, and per history turn.

For one evaluated direction (agent, its partner the user) of a clip cut into K whole turns of F frames
(S samples), every quantity is computed from ONE turn's inputs at a time (the user's motion, the user's
speech, the agent's speech of that turn; never the agent's motion), exactly the chunks the protocol hands
over, so a row can only use the turns a model with context n sees.

Per turn k, from that turn's chunk alone:

- ``mel`` (F, 2·G): the 40-band log-mel of each person's 1-s audio (:func:`~dyadbench.features.logmel.logmel_frames`
  on the chunk, agent first), averaged in G = :data:`MEL_GROUPS` groups of adjacent bands;
- partner motion (F, 56).

Current-turn block (frame f of turn k; identical for every n), :data:`CURRENT_DIM` columns:

    [ mel[k, max(f − L, 0)] for L in SPEECH_LAGS ] ++ [ user_motion[k, max(f − L, 0)] for L in MOTION_LAGS ]
    ++ mean_f mel[k] ++ mean_f user_motion[k]

(causal lags clipped to the turn's first frame: a lag never reaches into the previous turn).

Summary of turn j (used as history), :data:`SUMMARY_DIM` columns:

    mean_f user_motion[j] (56) ++ log std_f of each partner component (exp, jaw, pose: 3)
    ++ mean_f mel[j] (2·G) ++ speaking fraction of agent and user (2) ++ 1 (the turn exists)

The speaking fraction is the share of the turn's frames whose RMS level exceeds :data:`SPEAKING_DB` dBFS
(a fixed threshold, so it is causal; synthetic speech sits near −25 dBFS, silence near −60 dBFS).

Row of frame f of turn k for context n: ``[1, current(k, f), summary(k−1), …, summary(k−n)]`` with a summary
of zeros for a turn before the clip's start (k − d < 0), whose "exists" column is then 0. The rows for
n are therefore the first :func:`columns` (n) columns of the rows for :data:`MAX_CONTEXT`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from dyadbench.datasets.base import DyadicClip
from dyadbench.errors import InputError
from dyadbench.features.activity import frame_level_db
from dyadbench.features.logmel import logmel_frames
from dyadbench.motion import FLAME56, FLAME_COMPONENTS
from dyadbench.protocol.config import ProtocolConfig

MAX_CONTEXT = 7
N_MELS = 40
MEL_GROUPS = 8  # groups of N_MELS / MEL_GROUPS adjacent log-mel bands
SPEECH_LAGS = (0, 3, 6, 10, 15)  # frames (0–0.6 s at 25 fps)
MOTION_LAGS = (0, 6, 12)  # frames (0–0.48 s at 25 fps)
SPEAKING_DB = -45.0
MOTION_DIM = FLAME56.dim
SPEECH_DIM = 2 * MEL_GROUPS
CURRENT_DIM = len(SPEECH_LAGS) * SPEECH_DIM + len(MOTION_LAGS) * MOTION_DIM + SPEECH_DIM + MOTION_DIM
SUMMARY_DIM = MOTION_DIM + len(FLAME_COMPONENTS) + SPEECH_DIM + 2 + 1
STD_FLOOR = 1e-6


def columns(context: int) -> int:
    """Columns of a row for context n: the constant, the current-turn block and n turn summaries."""
    if not 0 <= context <= MAX_CONTEXT:
        raise InputError(None, f"context must be in 0..{MAX_CONTEXT}, got {context}")
    return 1 + CURRENT_DIM + context * SUMMARY_DIM


@dataclass(frozen=True)
class Direction:
    """One evaluated direction: its rows for n = MAX_CONTEXT, and what its prediction is scored against.

    ``rows`` (K·F, :func:`columns` (MAX_CONTEXT)); ``target`` (K·F, 56) the agent's motion of the whole turns;
    ``partner`` (K·F, 56) the partner's motion of the same frames.
    """

    stem: str
    rows: np.ndarray
    target: np.ndarray
    partner: np.ndarray


def _turn_chunks(audio: np.ndarray, turns: int, samples: int) -> np.ndarray:
    """(K, S) each turn's audio chunk, zero-padded past the recording's end (as the protocol pads it)."""
    audio = np.asarray(audio, np.float64)[:turns * samples]
    padded = np.zeros(turns * samples)
    padded[:len(audio)] = audio
    return padded.reshape(turns, samples)


def _turn_mel(chunks: np.ndarray, sample_rate: int, fps: float) -> np.ndarray:
    """(K, F, G) grouped log-mel of each turn's own audio chunk."""
    out = []
    for chunk in chunks:
        mel = logmel_frames(chunk, sample_rate, fps, n_mels=N_MELS)
        out.append(mel.reshape(mel.shape[0], MEL_GROUPS, -1).mean(axis=2))
    return np.stack(out)


def _speaking(chunks: np.ndarray, sample_rate: int, fps: float) -> np.ndarray:
    """(K,) share of each turn's frames above :data:`SPEAKING_DB`."""
    return np.array([np.mean(frame_level_db(chunk, sample_rate, fps) > SPEAKING_DB) for chunk in chunks])


def _lagged(turns: np.ndarray, lags: tuple[int, ...]) -> np.ndarray:
    """(K, F, d) -> (K, F, len(lags)·d): frame f carries frames max(f − L, 0) of the same turn."""
    frames = np.arange(turns.shape[1])
    return np.concatenate([turns[:, np.maximum(frames - lag, 0)] for lag in lags], axis=2)


def _summaries(user_motion: np.ndarray, mel: np.ndarray, speaking: np.ndarray) -> np.ndarray:
    """(K, SUMMARY_DIM) summary of each turn (see the module docstring)."""
    spread = [np.log(FLAME56.component(user_motion, c).std(axis=1).mean(axis=1) + STD_FLOOR)
              for c in FLAME_COMPONENTS]
    return np.concatenate([user_motion.mean(axis=1), np.stack(spread, axis=1), mel.mean(axis=1), speaking,
                           np.ones((len(speaking), 1))], axis=1)


def direction_features(clip: DyadicClip, agent: str, turn_seconds: float = 1.0) -> Direction:
    """Rows, target and partner motion of the whole turns of one direction of ``clip`` (``agent`` generated),
    turns of ``turn_seconds`` as the protocol cuts them (:class:`~dyadbench.protocol.config.ProtocolConfig`)."""
    stem = f"{clip.clip_id}_{agent}"
    me, partner = clip.participant(agent), clip.partner_of(agent)
    if partner is None:
        raise InputError(stem, "the context headroom needs two-participant clips (partner features)")
    config = ProtocolConfig(turn_seconds=turn_seconds, context=MAX_CONTEXT)
    F, S = config.frames_per_turn(clip.fps), config.samples_per_turn(clip.sample_rate)
    K = clip.num_frames // F
    if K == 0:
        raise InputError(stem, f"clip has {clip.num_frames} frames, shorter than one turn ({F} frames)")
    user_motion = np.asarray(partner.motion[:K * F], np.float64).reshape(K, F, -1)
    chunks = [_turn_chunks(p.audio, K, S) for p in (me, partner)]
    mel = np.concatenate([_turn_mel(c, clip.sample_rate, clip.fps) for c in chunks], axis=2)
    speaking = np.stack([_speaking(c, clip.sample_rate, clip.fps) for c in chunks], axis=1)
    current = np.concatenate([_lagged(mel, SPEECH_LAGS), _lagged(user_motion, MOTION_LAGS),
                              np.repeat(mel.mean(axis=1, keepdims=True), F, axis=1),
                              np.repeat(user_motion.mean(axis=1, keepdims=True), F, axis=1)], axis=2)
    summary = _summaries(user_motion, mel, speaking)
    history = np.zeros((K, MAX_CONTEXT * SUMMARY_DIM))
    for d in range(1, MAX_CONTEXT + 1):
        history[d:, (d - 1) * SUMMARY_DIM:d * SUMMARY_DIM] = summary[:max(K - d, 0)]
    rows = np.concatenate([np.ones((K, F, 1)), current, np.repeat(history[:, None], F, axis=1)], axis=2)
    return Direction(stem=stem, rows=rows.reshape(K * F, -1),
                     target=np.asarray(me.motion[:K * F], np.float64),
                     partner=user_motion.reshape(K * F, -1))
