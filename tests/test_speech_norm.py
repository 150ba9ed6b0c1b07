"""The ``speech_norm`` protocol setting: window (causal default) or clip (whole-clip waveform statistics)."""

from __future__ import annotations

import numpy as np
import pytest

from dyadbench.errors import ConfigError
from dyadbench.features import wav2vec
from dyadbench.protocol.causality import check_causal, perturb_after
from dyadbench.protocol.config import ProtocolConfig, variant_label
from dyadbench.protocol.interface import ModelInfo, StreamContext, StreamingModel, TurnInput
from dyadbench.protocol.streaming import stream_context
from tests.timar_official_fixture import WAV2VEC, arrays, fixture_clip, pcm_audio


@pytest.fixture(scope="module")
def fixture_arrays():
    return arrays()


def test_the_setting_is_validated_and_named_in_variant_labels():
    with pytest.raises(ConfigError, match="speech_norm must be one of window, clip"):
        ProtocolConfig(speech_norm="turn")
    assert variant_label(speech_norm="clip") == "speech-clip"
    assert variant_label(speech_norm="window", cfg_scale=1.5) == "cfg1.5"


def test_clip_hands_over_each_participants_whole_clip_statistics(fixture_arrays):
    inputs, _ = fixture_arrays
    clip = fixture_clip(inputs)
    window = stream_context(clip, "speaker2", ProtocolConfig())
    assert (window.speech_norm, window.agent_audio_stats, window.user_audio_stats) == ("window", None, None)
    ctx = stream_context(clip, "speaker2", ProtocolConfig(speech_norm="clip"))
    for stats, who in ((ctx.agent_audio_stats, "agent"), (ctx.user_audio_stats, "user")):
        x = pcm_audio(inputs, who).astype(np.float64)  # the statistics by an independent float64 formula
        assert stats == pytest.approx((x.mean(), ((x - x.mean()) ** 2).mean()), rel=1e-5, abs=1e-9)


def test_clip_normalisation_gives_the_released_waveform_and_speech_features(fixture_arrays):
    inputs, outputs = fixture_arrays
    model = wav2vec.load_wav2vec(WAV2VEC)
    ctx = stream_context(fixture_clip(inputs), "speaker2", ProtocolConfig(speech_norm="clip"))
    for who, stats in (("user", ctx.user_audio_stats), ("agent", ctx.agent_audio_stats)):
        audio = pcm_audio(inputs, who)
        np.testing.assert_array_equal(wav2vec.normalise(audio, stats), inputs[f"speech_{who}"])
        turns = outputs[f"speech_feats_{who}"].shape[0]
        per_turn = np.stack([wav2vec.wav2vec_frames(model, audio[t * 16_000:(t + 1) * 16_000], stats=stats)
                             for t in range(turns)])
        assert np.abs(per_turn - outputs[f"speech_feats_{who}"]).max() < 1e-4
        own = np.stack([wav2vec.wav2vec_frames(model, audio[t * 16_000:(t + 1) * 16_000]) for t in range(turns)])
        assert np.abs(own - outputs[f"speech_feats_{who}"]).max() > 0.1  # window statistics are not the release's


class StatsReader(StreamingModel):
    """Outputs the agent's clip mean plus the mean of the current turn's user audio (reads both channels)."""

    info = ModelInfo(name="stats-reader")

    def start_stream(self, ctx: StreamContext) -> None:
        self.mean = ctx.agent_audio_stats[0] if ctx.agent_audio_stats else 0.0

    def predict_turn(self, turn: TurnInput) -> np.ndarray:
        return np.full((turn.frames_per_turn, 56), self.mean + turn.current_user_audio.mean(), np.float32)


def test_the_causality_check_holds_clip_statistics_fixed_and_still_sees_later_inputs(fixture_arrays):
    clip = fixture_clip(fixture_arrays[0])
    config = ProtocolConfig(context=2, speech_norm="clip")
    changed = perturb_after(clip, 4 * 25, agent="speaker2")
    assert stream_context(changed, "speaker2", config).agent_audio_stats != \
        stream_context(clip, "speaker2", config).agent_audio_stats  # the statistics do see future audio
    check_causal(StatsReader, clip, "speaker2", config, turn=3)
