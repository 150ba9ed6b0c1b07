"""Training windows for TIMAR: features computed once per clip, 8-turn windows of both directions.

Each clip is cut to whole turns; the speech frontend runs once per participant, chunk by chunk. A
window is ``max_turns`` consecutive turns starting at a multiple of ``stride_turns`` turns, in both
directions (agent = each participant, user = the other). The data digest hashes the clip ids, motion
and audio bytes, so a checkpoint records exactly which data it was trained on.

Layouts with a validity column (``seamless``, :mod:`models.timar.layouts`): the model's motion is the
generated columns, and each participant's validity flags travel with the window (``user_valid``,
``agent_valid``) so the loss leaves invalid agent frames out and invalid user frames become null tokens.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass

import numpy as np
import torch
from tqdm import tqdm

from dyadbench.datasets.base import ClipSource, DyadicClip
from dyadbench.errors import InputError
from dyadbench.features.wav2vec import waveform_stats
from models.timar.config import MOTION_STD_FLOOR, TimarConfig
from models.timar.frontends import SpeechFrontend
from models.timar.layouts import timar_layout


@dataclass(frozen=True)
class ParticipantFeatures:
    speech: np.ndarray  # (turns·F, speech_dim) float32
    motion: np.ndarray  # (turns·F, motion_dim) float32: the generated columns
    valid: np.ndarray | None = None  # (turns·F,) bool, layouts with a validity column only


def clip_features(clip: DyadicClip, frontend: SpeechFrontend, cfg: TimarConfig) -> dict[str, ParticipantFeatures]:
    layout = timar_layout(cfg.motion_dim)
    if len(clip.participants) != 2 or clip.layout != layout.name:
        raise InputError(clip.clip_id, f"this TIMAR configuration trains on two-participant {layout.name} clips, "
                                       f"not {len(clip.participants)}-participant {clip.layout} clips")
    if clip.fps * cfg.samples_per_turn != clip.sample_rate * cfg.frames_per_turn:
        raise InputError(clip.clip_id, f"{clip.fps} fps / {clip.sample_rate} Hz do not match the model's turn of "
                                       f"{cfg.frames_per_turn} frames / {cfg.samples_per_turn} samples")
    turns = clip.num_frames // cfg.frames_per_turn
    frames = turns * cfg.frames_per_turn
    out = {}
    for p in clip.participants:
        audio = np.zeros(turns * cfg.samples_per_turn, np.float32)
        usable = min(len(p.audio), len(audio))
        audio[:usable] = p.audio[:usable]
        motion = np.asarray(p.motion[:frames], dtype=np.float32)
        valid = None if layout.valid_column is None else motion[:, layout.valid_column] > 0.5
        out[p.name] = ParticipantFeatures(frontend.features(audio, turns, waveform_stats(p.audio)),
                                          motion[:, :layout.motion_dim], valid)
    return out


def data_digest(source: ClipSource) -> str:
    """sha256 over the sorted clip ids and each participant's name, motion and audio bytes."""
    h = hashlib.sha256()
    for clip in source:
        h.update(clip.clip_id.encode())
        for p in clip.participants:
            h.update(p.name.encode())
            h.update(np.ascontiguousarray(p.motion, dtype=np.float32).tobytes())
            h.update(np.ascontiguousarray(p.audio, dtype=np.float32).tobytes())
    return h.hexdigest()


class WindowDataset(torch.utils.data.Dataset):
    """Items: dict of user_speech, user_motion, agent_speech, agent_motion, each (max_turns·F, ·)."""

    def __init__(self, source: ClipSource, frontend: SpeechFrontend, cfg: TimarConfig, stride_turns: int = 8,
                 progress: bool = True):
        if stride_turns < 1:
            raise InputError(source.describe().get("dataset"), f"stride must be >= 1 turn, got {stride_turns}")
        self.cfg = cfg
        self.features: list[dict[str, ParticipantFeatures]] = []
        self.windows: list[tuple[int, str, str, int]] = []  # (clip index, agent, user, first frame)
        F, width = cfg.frames_per_turn, cfg.max_turns
        for clip in tqdm(source, total=len(source), desc="speech features", disable=not progress):
            feats = clip_features(clip, frontend, cfg)
            turns = clip.num_frames // F
            index = len(self.features)
            self.features.append(feats)
            names = [p.name for p in clip.participants]
            for start in range(0, turns - width + 1, stride_turns):
                for agent, user in (names, names[::-1]):
                    self.windows.append((index, agent, user, start * F))
        if not self.windows:
            raise InputError(source.describe().get("dataset"), f"no clip holds {width} whole turns to train on")

    def __len__(self) -> int:
        return len(self.windows)

    def __getitem__(self, i: int) -> dict[str, torch.Tensor]:
        index, agent, user, start = self.windows[i]
        stop = start + self.cfg.max_turns * self.cfg.frames_per_turn
        a, u = self.features[index][agent], self.features[index][user]
        item = {"user_speech": torch.from_numpy(u.speech[start:stop]),
                "user_motion": torch.from_numpy(u.motion[start:stop]),
                "agent_speech": torch.from_numpy(a.speech[start:stop]),
                "agent_motion": torch.from_numpy(a.motion[start:stop])}
        if a.valid is not None:
            item["user_valid"] = torch.from_numpy(u.valid[start:stop])
            item["agent_valid"] = torch.from_numpy(a.valid[start:stop])
        return item

    def speech_statistics(self) -> tuple[np.ndarray, np.ndarray]:
        """Per-dimension mean and standard deviation of all speech features (normalisation)."""
        allf = np.concatenate([f.speech for feats in self.features for f in feats.values()], axis=0)
        return allf.mean(0), np.maximum(allf.std(0), 1e-6)

    def motion_statistics(self) -> tuple[np.ndarray, np.ndarray]:
        """Per-dimension mean and standard deviation (floored at ``MOTION_STD_FLOOR``) of the motion of
        every participant and frame of the training clips (``motion_norm = "per_dim"``); valid frames only
        in layouts with a validity column."""
        allm = np.concatenate([f.motion if f.valid is None else f.motion[f.valid]
                               for feats in self.features for f in feats.values()], axis=0)
        allm = allm.astype(np.float64)
        return allm.mean(0).astype(np.float32), np.maximum(allm.std(0), MOTION_STD_FLOOR).astype(np.float32)
