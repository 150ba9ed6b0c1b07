"""The released DualTalk checkpoint format against the public official-code fixtures (dualtalk_b).

Reference values come from the released code (float64 run, and an unmodified float32 run for
``*_f32run``); see ``tests/fixtures/official/dualtalk_b/README.md``.
"""

from __future__ import annotations

import pickle
from collections import OrderedDict
from pathlib import Path

import numpy as np
import pytest
import torch

from dyadbench.errors import InputError
from dyadbench.protocol.interface import ModelOptions, StreamContext
from models.dualtalk.official import load_official
from models.dualtalk.registry import build_dualtalk_offline, load_dualtalk
from models.dualtalk.speech import frame_count

FIXTURES = Path(__file__).resolve().parent / "fixtures" / "official"
DT = FIXTURES / "dualtalk_b"
CHECKPOINT, WAV2VEC = DT / "checkpoint.pth", DT / "wav2vec-tiny"
STAGES = ("audio_feat1", "audio_feat2", "blendshape_feat", "temporal_feat", "interaction_feat", "output")
# float32 against the float64 release: wav2vec states (and their projections) 1e-4, the rest 1e-5 (README)
F32_TOLERANCE = {"audio_feat1": 1e-4, "audio_feat2": 1e-4}



@pytest.fixture(scope="module")
def inputs():
    return dict(np.load(DT / "inputs.npz"))


@pytest.fixture(scope="module")
def reference():
    return dict(np.load(DT / "outputs.npz"))


@pytest.fixture(scope="module")
def model():
    return load_official(CHECKPOINT, WAV2VEC)


def run(model, inputs, dtype=torch.float32) -> dict[str, np.ndarray]:
    """Every stage and both wav2vec states on the fixture inputs (the model cast to ``dtype``)."""
    m = model.to(dtype)
    a1, a2, b2 = (torch.from_numpy(inputs[k]).to(dtype)[None] for k in ("audio1", "audio2", "blendshape2"))
    frames = frame_count(len(inputs["audio1"]))
    with torch.no_grad():
        out = {k: v[0].numpy() for k, v in m.stages(a1, a2, b2, frames).items()}
        for i, audio in ((1, a1), (2, a2)):
            out[f"w2v_audio{i}_last_hidden_state"] = m.joint_encoder.speech_states(audio, i, frames)[0].numpy()
    m.float()
    return out


def max_diff(a, b) -> float:
    return float(np.abs(np.asarray(a, np.float64) - np.asarray(b, np.float64)).max())


def test_frame_count_is_the_floating_point_ceiling(reference, inputs):
    assert frame_count(len(inputs["audio1"])) == int(reference["frame_num"]) == 141
    assert frame_count(4480) == 8  # 4480 / 16000 * 25 = 7.000000000000001 in floating point (exact: 7)


def test_float64_run_reproduces_every_stage(model, inputs, reference):
    out = run(model, inputs, torch.float64)
    for name in (*STAGES, "w2v_audio1_last_hidden_state", "w2v_audio2_last_hidden_state"):
        assert out[name].shape == reference[name].shape
        assert max_diff(out[name], reference[name]) < 1e-9, name


def test_float32_run_matches_the_release(model, inputs, reference):
    out = run(model, inputs)
    for name in STAGES:
        assert max_diff(out[name], reference[name]) < F32_TOLERANCE.get(name, 1e-5), name
    for i in (1, 2):
        name = f"w2v_audio{i}_last_hidden_state"
        assert max_diff(out[name], reference[name]) < 1e-4, name
    assert max_diff(out["output"], reference["output_f32run"]) < 1e-5
    assert max_diff(out["w2v_audio1_last_hidden_state"], reference["w2v_audio1_last_hidden_state_f32run"]) < 1e-5


def test_swapped_or_pretrained_encoders_fail_the_fixture(model, inputs, reference):
    from transformers import Wav2Vec2Model

    enc = model.joint_encoder
    enc.audio_encoder1, enc.audio_encoder2 = enc.audio_encoder2, enc.audio_encoder1
    try:
        swapped = max_diff(run(model, inputs)["output"], reference["output"])
    finally:
        enc.audio_encoder1, enc.audio_encoder2 = enc.audio_encoder2, enc.audio_encoder1
    assert swapped > 1e-2
    pretrained = load_official(CHECKPOINT, WAV2VEC)
    for name in ("audio_encoder1", "audio_encoder2"):
        setattr(pretrained.joint_encoder, name, Wav2Vec2Model.from_pretrained(str(WAV2VEC)).eval())
    assert max_diff(run(pretrained, inputs)["output"], reference["output"]) > 1e-2


def test_offline_model_from_pcm16_matches_the_release(inputs, reference):
    """End to end: the registered offline model on the wav samples (whole-clip normalisation inside)."""
    model = build_dualtalk_offline(ModelOptions(weights=CHECKPOINT, extra={"wav2vec_weights": str(WAV2VEC)}))
    ctx = StreamContext("fixture", "speaker1", "speaker2", 25.0, 16_000, 25, 16_000, 0, 5, 0)
    pcm = {k: inputs[f"{k}_pcm16"].astype(np.float32) / 32768 for k in ("audio1", "audio2")}
    out = model.predict_clip(ctx, inputs["blendshape2"], pcm["audio2"], pcm["audio1"])
    assert out.shape == reference["output"].shape
    assert max_diff(out, reference["output"]) < 1e-5
    assert model.info.name == "dualtalk-offline" and model.info.config["weights_format"] == "official"


def _save(tmp_path: Path, state: dict) -> Path:
    path = tmp_path / "DualTalk.pth"
    torch.save(state, path)
    return path


def test_missing_and_unexpected_keys_are_listed(tmp_path):
    state = torch.load(CHECKPOINT, weights_only=True)
    assert any(k.endswith("pos_conv_embed.conv.weight_g") for k in state)  # the release's old names load as is
    missing = OrderedDict((k, v) for k, v in state.items() if k != "temporal_enhancer.temporal_lstm.bias_hh_l1")
    with pytest.raises(InputError, match=r"missing: temporal_enhancer\.temporal_lstm\.bias_hh_l1") as err:
        load_official(_save(tmp_path, missing), WAV2VEC)
    assert "DualTalk.pth" in str(err.value)
    extra = OrderedDict(state, **{"synthesis_module.extra_head.weight": torch.zeros(2)})
    with pytest.raises(InputError, match=r"unexpected: synthesis_module\.extra_head\.weight"):
        load_official(_save(tmp_path, extra), WAV2VEC)


def test_foreign_truncated_and_pickled_files_are_refused(tmp_path):
    timar = FIXTURES / "timar_b" / "checkpoint.pth"
    with pytest.raises(InputError, match="checkpoint.pth") as err:
        load_dualtalk(timar, str(WAV2VEC))
    assert "argparse.Namespace" in str(err.value) or "not a DualTalk checkpoint" in str(err.value)
    truncated = tmp_path / "truncated.pth"
    truncated.write_bytes(CHECKPOINT.read_bytes()[:50_000])
    with pytest.raises(InputError, match="truncated.pth"):
        load_dualtalk(truncated, str(WAV2VEC))
    hostile = tmp_path / "hostile.pth"
    torch.save({"joint_encoder.audio_projection.weight": torch.zeros(2), "payload": Path("x")}, hostile)
    with pytest.raises(InputError, match="hostile.pth.*refused"):
        load_dualtalk(hostile, str(WAV2VEC))
    plain = tmp_path / "plain.pth"
    plain.write_bytes(pickle.dumps({"a": 1}))
    with pytest.raises(InputError, match="plain.pth"):
        load_dualtalk(plain, str(WAV2VEC))


def test_official_checkpoint_needs_a_wav2vec_config_folder(tmp_path):
    from dyadbench.errors import ConfigError

    with pytest.raises(ConfigError, match="wav2vec"):
        load_dualtalk(CHECKPOINT, None)
    with pytest.raises(InputError, match="config.json"):
        load_dualtalk(CHECKPOINT, str(tmp_path))
