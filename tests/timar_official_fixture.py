"""The released-code TIMAR fixture (``tests/fixtures/official/timar_b``, a copy of the public fixture) as test helpers.

The fixture's README states its arrays: ``inputs.npz`` (PCM16 speech of user = speaker1 and agent =
speaker2, motion [exp | jaw | neck]) and ``outputs.npz`` (what the released code computes from them).
Its model factory ``timar_tiny_b`` has 3 attention heads, which the checkpoint does not store.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from dyadbench.datasets.base import DyadicClip, Participant
from dyadbench.datasets.wav import write_wav

FIXTURE = Path(__file__).resolve().parent / "fixtures" / "official" / "timar_b"
CHECKPOINT = FIXTURE / "checkpoint.pth"
WAV2VEC = FIXTURE / "wav2vec-tiny"
HEADS = 3  # timar_tiny_b (fixture README: "Number of attention heads ... 3 here")
CLIP_ID = "fixture"



def arrays() -> tuple[dict, dict]:
    """(inputs, outputs) of the fixture as dicts of numpy arrays."""
    with np.load(FIXTURE / "inputs.npz") as i, np.load(FIXTURE / "outputs.npz") as o:
        return dict(i), dict(o)


def pcm_audio(inputs: dict, who: str) -> np.ndarray:
    """The waveform as the release reads the wav: int16 / 32768 in float32."""
    return inputs[f"speech_{who}_pcm16"].astype(np.float32) / 32768


def fixture_clip(inputs: dict) -> DyadicClip:
    """The fixture's dialogue: speaker1 = user (partner), speaker2 = agent (generated)."""
    user = Participant("speaker1", inputs["motion_user"], pcm_audio(inputs, "user"))
    agent = Participant("speaker2", inputs["motion_agent"], pcm_audio(inputs, "agent"))
    return DyadicClip(CLIP_ID, (user, agent), agents=("speaker2",))


def write_dualtalk_split(inputs: dict, folder: Path) -> Path:
    """The fixture clip as a DualTalk split folder (wav PCM16; npz exp and pose = [neck | jaw])."""
    folder.mkdir(parents=True, exist_ok=True)
    for speaker, who in (("speaker1", "user"), ("speaker2", "agent")):
        motion = inputs[f"motion_{who}"]
        write_wav(folder / f"{CLIP_ID}_{speaker}.wav", pcm_audio(inputs, who))
        np.savez(folder / f"{CLIP_ID}_{speaker}.npz", exp=motion[:, :50],
                 pose=np.concatenate([motion[:, 53:56], motion[:, 50:53]], axis=1))
    return folder
