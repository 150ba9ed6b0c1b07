"""Training data for SFMS from dyadbench clips: normalised motion, speaker log-mel rows, windows.

- Motion is z-scored per dim with train-split statistics (both participants pooled); the neutral
  frame is the zero vector of that space (spec §1.3).
- Speaker audio: log-mel rows at ``audio_rows_per_frame`` rows per motion frame (hop 10 ms at 25 fps),
  standardised per bin with train statistics. A dataset that ships speech features instead of a
  waveform (Learning2Listen: 4 rows of a 128-bin mel per frame) is read as shipped; they must have the
  predictor's ``audio_bins`` and ``audio_rows_per_frame``.
- A *directed* clip pairs a listener (the generated participant) with the partner as speaker; every
  participant a clip generates (``DyadicClip.agent_participants``: both for the embedded corpus, the
  listener for Learning2Listen) gives one direction.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Iterable

import numpy as np

from dyadbench.datasets.base import DyadicClip
from dyadbench.errors import InputError
from dyadbench.features.logmel import logmel_frames
from dyadbench.protocol.streaming import feature_window
from models.sfms.config import PredictorConfig

STD_FLOOR = 1e-4


def motion_stats(arrays: list[np.ndarray], normalisation: str = "zscore") -> tuple[np.ndarray, np.ndarray]:
    """Per-dim mean over all frames of ``arrays`` and a scale (floored at 1e-4), by ``normalisation`` (D22):

    - "zscore": the std over all frames, σ_d = sqrt(mean_f (x_fd − μ_d)²);
    - "within-sequence": the pooled within-sequence std, σ_d = sqrt(Σ_s Σ_f (x_sfd − μ_sd)² / Σ_s T_s),
      so a dim that moves little inside a sequence but differs between sequences (head pose) is not
      shrunk to near-constant in the normalised space.
    """
    stacked = np.concatenate(arrays, axis=0).astype(np.float64)
    if normalisation == "within-sequence":
        sq = sum(((a.astype(np.float64) - a.mean(0)) ** 2).sum(0) for a in arrays)
        std = np.sqrt(sq / len(stacked))
    else:
        std = stacked.std(0)
    return stacked.mean(0).astype(np.float32), np.maximum(std, STD_FLOOR).astype(np.float32)


def clip_motions(clips: Iterable[DyadicClip]) -> list[np.ndarray]:
    """Every participant's motion of every clip, float32 (clips may be a generator: audio is not kept)."""
    return [np.asarray(p.motion, dtype=np.float32) for c in clips for p in c.participants]


def speech_rows(audio: np.ndarray, sample_rate: int, fps: float, cfg: PredictorConfig) -> np.ndarray:
    """Log-mel rows (floor(len·fps/sr)·rows, bins) float32 of one speech signal."""
    return logmel_frames(audio, sample_rate, fps * cfg.audio_rows_per_frame, n_mels=cfg.audio_bins,
                         win_length=int(round(cfg.audio_window_s * sample_rate)))


def speaker_rows(features: np.ndarray | None, audio: np.ndarray, frames: int, sample_rate: int, fps: float,
                 cfg: PredictorConfig, source: str) -> np.ndarray:
    """The predictor's speech rows for ``frames`` motion frames: the dataset's own speech features when it
    ships them (checked against ``audio_bins`` and ``audio_rows_per_frame``), else the log-mel of ``audio``;
    zeros (never read) for a predictor without an audio branch (``speaker_audio = "none"``, D33)."""
    if cfg.speaker_audio == "none":
        return np.zeros((frames * cfg.audio_rows_per_frame, cfg.audio_bins), np.float32)
    if features is not None:
        rows, bins = features.shape
        if bins != cfg.audio_bins or rows != frames * cfg.audio_rows_per_frame:
            raise InputError(source, f"the dataset ships speech features of {bins} bins × {rows / max(frames, 1):g} "
                                     f"rows per frame; this SFMS predictor reads {cfg.audio_bins} × "
                                     f"{cfg.audio_rows_per_frame} (train one on this dataset: `dyadbench train "
                                     f"sfms ... --set audio_bins={bins}`)")
        return np.asarray(features, np.float32)
    if np.size(audio) == 0:
        raise InputError(source, "no speech: neither a waveform nor speech features")
    return speech_rows(np.asarray(audio, np.float32), sample_rate, fps, cfg)


@dataclass(frozen=True)
class DirectedClip:
    """One listener/speaker direction of a clip, all normalised: motion (T, d), audio (T·rows, bins)."""

    name: str
    listener: np.ndarray
    speaker: np.ndarray
    audio: np.ndarray


def directed_clips(clips: Iterable[DyadicClip], cfg: PredictorConfig
                   ) -> list[tuple[str, np.ndarray, np.ndarray, np.ndarray]]:
    """Raw (name, listener motion, speaker motion, speaker rows) for every generated direction of every clip.

    ``clips`` may be a generator, so a large split is read one clip at a time (waveforms are dropped).
    """
    out = []
    for clip in clips:
        if len(clip.participants) != 2:
            raise InputError(clip.clip_id, "SFMS needs two-participant clips (a listener and a speaker)")
        t = clip.num_frames
        for listener in clip.agent_participants:
            speaker = clip.partner_of(listener.name)
            rows = speaker_rows(feature_window(speaker, 0, t), speaker.audio, t, clip.sample_rate, clip.fps, cfg,
                                f"{clip.clip_id}_{speaker.name}")
            rows = rows[: t * cfg.audio_rows_per_frame]
            if rows.shape[0] < t * cfg.audio_rows_per_frame:
                raise InputError(f"{clip.clip_id}_{speaker.name}", f"speech shorter than the motion ({t} frames)")
            out.append((f"{clip.clip_id}_{listener.name}", np.asarray(listener.motion[:t], np.float32),
                        np.asarray(speaker.motion[:t], np.float32), rows))
    return out


def row_stats(raw: list[tuple[str, np.ndarray, np.ndarray, np.ndarray]]) -> tuple[np.ndarray, np.ndarray]:
    """Per-bin mean and std (floored at 1e-4) of the speaker rows of directed clips, accumulated in float64."""
    total = sum(float(r[3].shape[0]) for r in raw)
    s1 = sum(r[3].sum(0, dtype=np.float64) for r in raw)
    s2 = sum(np.square(r[3], dtype=np.float64).sum(0) for r in raw)
    mean = s1 / total
    std = np.sqrt(np.maximum(s2 / total - mean ** 2, 0.0))
    return mean.astype(np.float32), np.maximum(std, STD_FLOOR).astype(np.float32)


def normalise_directed(raw: list[tuple[str, np.ndarray, np.ndarray, np.ndarray]], motion_mean: np.ndarray,
                       motion_std: np.ndarray, audio_mean: np.ndarray, audio_std: np.ndarray) -> list[DirectedClip]:
    return [DirectedClip(name, (lis - motion_mean) / motion_std, (spk - motion_mean) / motion_std,
                         (rows - audio_mean) / audio_std) for name, lis, spk, rows in raw]


def sample_motion_windows(arrays: list[np.ndarray], batch: int, window: int, rng: np.random.Generator) -> np.ndarray:
    """(batch, window, d) random crops; arrays drawn in proportion to their number of crops."""
    counts = np.array([max(a.shape[0] - window + 1, 0) for a in arrays], dtype=np.float64)
    if counts.sum() == 0:
        raise InputError("training motion", f"no sequence is at least {window} frames long")
    which = rng.choice(len(arrays), size=batch, p=counts / counts.sum())
    return np.stack([arrays[i][o: o + window] for i, o in
                     ((i, rng.integers(0, counts[i])) for i in which)]).astype(np.float32)


@dataclass(frozen=True)
class PredictorBatch:
    """Listener windows (B, P+F, d) with the neutral/pre-start augmentation applied, the aligned speaker
    motion (B, P+F, d), its validity (B, P+F) bool and speaker rows (B, (P+F)·rows, bins); invalid = 0."""

    listener: np.ndarray
    speaker: np.ndarray
    valid: np.ndarray
    audio: np.ndarray


def sample_predictor_batch(clips: list[DirectedClip], cfg: PredictorConfig, batch: int,
                           rng: np.random.Generator) -> PredictorBatch:
    """Random training windows [t − past, t + future) (spec §3.4, D24)."""
    p, f, rows = cfg.past, cfg.future, cfg.audio_rows_per_frame
    w = p + f
    lengths = np.array([c.listener.shape[0] for c in clips])
    if (lengths < f).all():
        raise InputError("training clips", f"no clip has {f} frames")
    d, bins = clips[0].listener.shape[1], clips[0].audio.shape[1]
    lis = np.zeros((batch, w, d), np.float32)
    spk = np.zeros((batch, w, d), np.float32)
    valid = np.zeros((batch, w), bool)
    aud = np.zeros((batch, w * rows, bins), np.float32)
    weights = np.maximum(lengths - f + 1, 0).astype(np.float64)
    for b, i in enumerate(rng.choice(len(clips), size=batch, p=weights / weights.sum())):
        c, n = clips[i], lengths[i]
        if rng.random() < cfg.pre_start_prob or n - f < p:
            t = int(rng.integers(0, min(p, n - f) + 1))
        else:
            t = int(rng.integers(p, n - f + 1))
        lo = max(t - p, 0)
        off = lo - (t - p)
        lis[b, off:] = c.listener[lo: t + f]
        spk[b, off:] = c.speaker[lo: t + f]
        valid[b, off:] = True
        aud[b, off * rows:] = c.audio[lo * rows: (t + f) * rows]
        if rng.random() < cfg.neutral_prob:
            lis[b, : int(rng.integers(1, p + 1))] = 0.0
    return PredictorBatch(lis, spk, valid, aud)
