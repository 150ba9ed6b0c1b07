"""Nearest-neighbour retrieval: the agent motion of the train turn whose partner behaved most alike.

Index (fitted on the train split, cached by its digest): every whole turn of every generated direction
(both, or the clip's ``agents``) of up to ``MAX_TRAIN_CLIPS`` train clips (evenly spaced over the sorted
clip ids), except turns holding a frame the layout marks invalid for either participant
(:func:`baselines.fitting.valid_frames`; Seamless Interaction's zero-filled blocks), so no zero-filled
motion is ever retrieved. A turn is described by its partner's behaviour in that turn only:

- partner motion: per-dimension mean and standard deviation over the turn's frames (2·D values);
- partner speech: mean and standard deviation over the turn of the 40-band log-mel features of the
  turn's audio (:func:`dyadbench.features.logmel.logmel_frames`, one row per motion frame with the hop
  sample_rate / fps rounded to whole samples: 640 at 16 kHz / 25 fps, 533 at 30 fps; 80 values), or, for a dataset
  that ships speech features instead of a waveform (Learning2Listen), over the turn's feature rows
  (2·B values; the index records which, and a stream must match it).

Each feature is standardised with the index's mean and standard deviation, the motion and the speech
block are each divided by √(block size) so both weigh the same, and the result is projected on its
first ``PCA_DIMS`` principal axes. An exact k-d tree (:class:`scipy.spatial.cKDTree`) over the index
gives the nearest train turn (Euclidean); the model outputs that turn's agent motion. Every output turn
is therefore real train motion, chosen by what the partner did in the current turn only (no history).
"""

from __future__ import annotations

import math

import numpy as np
from scipy.spatial import cKDTree
from tqdm import tqdm

from baselines.fitting import cached_fit, open_train, valid_frames
from dyadbench.datasets.base import ClipSource
from dyadbench.errors import ConfigError, InputError
from dyadbench.features.logmel import logmel_frames
from dyadbench.protocol.config import ProtocolConfig
from dyadbench.protocol.interface import (ModelInfo, ModelOptions, OfflineModel, StreamContext, StreamingModel,
                                          TurnInput)

FIT_VERSION = 2
MAX_TRAIN_CLIPS = 256
PCA_DIMS = 24
N_MELS = 40


def turn_speech(user_audio: np.ndarray, user_features: np.ndarray | None, sample_rate: int, fps: float) -> np.ndarray:
    """Speech rows of K turns: the shipped features (K, R, B) when given, else the log-mel of each turn's
    audio (K, S) -> (K, F, N_MELS)."""
    if user_features is not None:
        return np.asarray(user_features, np.float64)
    rate = sample_rate / round(sample_rate / fps)  # whole-sample hop; only each turn's mean and std are used
    return np.stack([logmel_frames(a, sample_rate, rate, n_mels=N_MELS) for a in user_audio])


def partner_features(user_motion: np.ndarray, speech: np.ndarray) -> np.ndarray:
    """Raw features of K turns: user_motion (K, F, D), speech rows (K, R, B) -> (K, 2·D + 2·B)."""
    return np.concatenate([user_motion.mean(axis=1), user_motion.std(axis=1),
                           speech.mean(axis=1), speech.std(axis=1)], axis=1).astype(np.float64)


def speech_kind(features: np.ndarray | None) -> str:
    """What describes the partner's speech: ``log-mel`` of the waveform or the dataset's ``features-<B>``."""
    return "log-mel" if features is None else f"features-{features.shape[-1]}"


def split_turns(array: np.ndarray, num_turns: int, per_turn: int) -> np.ndarray:
    """(num_turns, per_turn, ...) view of the first num_turns·per_turn rows, zero-padded if short."""
    need = num_turns * per_turn
    if array.shape[0] < need:
        array = np.concatenate([array, np.zeros((need - array.shape[0],) + array.shape[1:], array.dtype)])
    return array[:need].reshape((num_turns, per_turn) + array.shape[1:])


def build_index(source: ClipSource, turn_seconds: float) -> dict[str, np.ndarray]:
    """Fit the retrieval index on ``source`` (see module docstring)."""
    ids = source.clip_ids()
    chosen = ids[::max(1, math.ceil(len(ids) / MAX_TRAIN_CLIPS))]
    config = ProtocolConfig(turn_seconds=turn_seconds, context=0)
    features, targets, kinds = [], [], set()
    fps = sample_rate = None
    for clip_id in tqdm(chosen, desc="building retrieval index", unit="clip", leave=False):
        clip = source.load(clip_id)
        if len(clip.participants) != 2:
            raise InputError(clip_id, "nn-retrieval needs two-participant clips (partner features)")
        fps, sample_rate = clip.fps, clip.sample_rate
        F, S = config.frames_per_turn(fps), config.samples_per_turn(sample_rate)
        K = clip.num_frames // F
        if K == 0:
            continue
        for agent in clip.agent_participants:
            user = clip.partner_of(agent.name)
            r = user.feature_rows_per_frame
            feats = None if r is None else split_turns(user.speech_features, K, F * r)
            speech = turn_speech(split_turns(np.asarray(user.audio, np.float32), K, S), feats, sample_rate, fps)
            valid = (split_turns(valid_frames(agent.motion, clip.layout), K, F).all(axis=1)
                     & split_turns(valid_frames(user.motion, clip.layout), K, F).all(axis=1))
            features.append(partner_features(split_turns(np.asarray(user.motion, np.float64), K, F), speech)[valid])
            targets.append(split_turns(np.asarray(agent.motion, np.float32), K, F)[valid])
            kinds.add(speech_kind(feats))
    if not sum(len(t) for t in targets):
        raise InputError(f"{source.dataset}/{source.split}", "no whole valid turns in the train clips")
    if len(kinds) > 1:
        raise InputError(f"{source.dataset}/{source.split}", f"partners' speech differs between clips: "
                                                             f"{', '.join(sorted(kinds))}")
    raw = np.concatenate(features)
    mean, std = raw.mean(axis=0), raw.std(axis=0)
    std[std < 1e-8] = 1.0
    motion_dims = 2 * targets[0].shape[-1]
    speech_dims = raw.shape[1] - motion_dims
    weights = np.concatenate([np.full(motion_dims, 1 / math.sqrt(motion_dims)),
                              np.full(speech_dims, 1 / math.sqrt(speech_dims))])
    z = (raw - mean) / std * weights
    _, _, vt = np.linalg.svd(z - z.mean(axis=0), full_matrices=False)
    axes = vt[:min(PCA_DIMS, vt.shape[0])]
    return {"feat_mean": mean, "feat_std": std, "weights": weights, "z_mean": z.mean(axis=0), "axes": axes,
            "points": (z - z.mean(axis=0)) @ axes.T, "targets": np.concatenate(targets),
            "fps": np.array(fps), "sample_rate": np.array(sample_rate), "clips": np.array(len(chosen)),
            "speech": np.array(kinds.pop())}


class NearestTurnRetrieval(StreamingModel, OfflineModel):
    """Output the agent motion of the nearest train turn by partner features (see module docstring)."""

    def __init__(self, info: ModelInfo, index: dict[str, np.ndarray]):
        self.info = info
        self.index = index
        self.tree = cKDTree(index["points"])
        self.frames_per_turn = index["targets"].shape[1]
        self._where = "stream"

    def _project(self, raw: np.ndarray) -> np.ndarray:
        ix = self.index
        return ((raw - ix["feat_mean"]) / ix["feat_std"] * ix["weights"] - ix["z_mean"]) @ ix["axes"].T

    def _check(self, ctx: StreamContext) -> None:
        if ctx.user is None:
            raise InputError(f"{ctx.clip_id}_{ctx.agent}", "nn-retrieval needs a partner; this session has none")
        if (ctx.frames_per_turn != self.frames_per_turn or ctx.fps != float(self.index["fps"])
                or ctx.sample_rate != int(self.index["sample_rate"])):
            raise ConfigError(f"nn-retrieval index was built for {self.frames_per_turn}-frame turns at "
                              f"{float(self.index['fps'])} fps / {int(self.index['sample_rate'])} Hz; the stream "
                              f"has {ctx.frames_per_turn}-frame turns at {ctx.fps} fps / {ctx.sample_rate} Hz")

    def _retrieve(self, user_motion: np.ndarray, user_audio: np.ndarray, user_features: np.ndarray | None,
                  sample_rate: int, fps: float, source: str) -> np.ndarray:
        kind, built = speech_kind(user_features), str(self.index["speech"])
        if kind != built:
            raise InputError(source, f"nn-retrieval's index describes the partner's speech by {built}; this "
                                     f"stream's partner has {kind}")
        speech = turn_speech(user_audio, user_features, sample_rate, fps)
        _, nearest = self.tree.query(self._project(partner_features(user_motion.astype(np.float64), speech)), k=1)
        return self.index["targets"][nearest]

    def start_stream(self, ctx: StreamContext) -> None:
        self._check(ctx)
        self._ctx = ctx

    def predict_turn(self, turn: TurnInput) -> np.ndarray:
        ctx, feats = self._ctx, turn.current_user_speech_features
        return self._retrieve(turn.current_user_motion[None], turn.current_user_audio[None],
                              None if feats is None else feats[None], ctx.sample_rate, ctx.fps,
                              f"{ctx.clip_id}_{ctx.user}")[0]

    def predict_clip(self, ctx: StreamContext, user_motion: np.ndarray, user_audio: np.ndarray,
                     agent_audio: np.ndarray) -> np.ndarray:
        self._check(ctx)
        K, F = ctx.num_turns, ctx.frames_per_turn
        turns = self._retrieve(split_turns(user_motion, K, F), split_turns(user_audio, K, ctx.samples_per_turn),
                               None, ctx.sample_rate, ctx.fps, f"{ctx.clip_id}_{ctx.user}").reshape(K * F, -1)
        tail = user_motion.shape[0] - K * F
        return np.concatenate([turns, np.repeat(turns[-1:], tail, axis=0)]) if tail else turns


def build_nn_retrieval(options: ModelOptions) -> NearestTurnRetrieval:
    source = open_train(options.train_split, "nn-retrieval")
    turn_seconds = float(options.extra.get("turn_seconds", 1.0))
    index, digest = cached_fit(f"nn-retrieval-t{turn_seconds:g}", FIT_VERSION, source,
                               lambda src: build_index(src, turn_seconds))
    info = ModelInfo(name="nn-retrieval", layout=options.extra.get("layout", "flame56"), version=str(FIT_VERSION),
                     weights_digest=digest,
                     config={"train": f"{source.dataset}/{source.split}", "index_clips": int(index["clips"]),
                             "index_turns": int(index["points"].shape[0]), "pca_dims": int(index["axes"].shape[0]),
                             "turn_seconds": turn_seconds})
    return NearestTurnRetrieval(info, index)
