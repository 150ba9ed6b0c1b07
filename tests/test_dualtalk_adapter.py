"""DualTalk adapter: round trip of generated folders, clear errors on bad folders, the real demo clips."""

import struct
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from dyadbench.datasets.dualtalk import DualTalkSource, folder_info, open_split, validate_folder
from dyadbench.datasets.dualtalk_files import load_gt_npz
from dyadbench.datasets.wav import read_wav, wav_bytes, write_wav
from dyadbench.errors import InputError
from dyadbench.features.activity import energy_vad
from dyadbench.datasets.statistics import motion_statistics
from dyadbench.synth.calibration import REAL_CLIPS
from dyadbench.synth.corpus import make_clip
from dyadbench.synth.writers import write_clip

DEMO = Path("/work/shared/data/dualtalk-demo")
needs_demo = pytest.mark.skipif(not DEMO.is_dir(), reason="real DualTalk demo clips not on this machine")


def write_split(folder: Path, n: int = 2, seconds: float = 3.0, split: str = "test") -> list:
    folder.mkdir(parents=True, exist_ok=True)
    clips = [make_clip(split, i, seed=1, duration_s=seconds) for i in range(n)]
    for clip in clips:
        write_clip(folder, clip, seed=1)
    return clips


def test_round_trip_every_field(tmp_path):
    clips = write_split(tmp_path / "test")
    source = open_split(tmp_path, "test")
    assert source.clip_ids() == [c.clip_id for c in clips]
    for clip in clips:
        back = source.load(clip.clip_id)
        assert (back.fps, back.sample_rate, back.layout) == (clip.fps, clip.sample_rate, clip.layout)
        for p, q in zip(clip.participants, back.participants):
            assert p.name == q.name
            assert q.motion.dtype == np.float32 and np.array_equal(p.motion, q.motion)
            assert q.audio.dtype == np.float32 and np.array_equal(p.audio, q.audio)
            assert q.identity is None  # the DualTalk release has no person ids
            assert np.array_equal(back.meta["speaking"][q.name], energy_vad(q.audio))
        assert back.meta["speaking_source"] == "energy-vad"


def test_npz_holds_dualtalk_order_and_release_keys(tmp_path):
    clip = write_split(tmp_path, n=1)[0]
    p = clip.participants[0]
    with np.load(tmp_path / f"{clip.clip_id}_speaker1.npz") as npz:
        assert sorted(npz.files) == ["cam", "exp", "light", "pose", "shape", "tex"]
        t = p.motion.shape[0]
        assert npz["shape"].shape == (t, 100) and npz["tex"].shape == (t, 50)
        assert npz["cam"].shape == (t, 3) and npz["light"].shape == (t, 9, 3)
        assert np.array_equal(npz["exp"], p.motion[:, :50])
        assert np.array_equal(npz["pose"][:, :3], p.motion[:, 53:56])  # head rotation first
        assert np.array_equal(npz["pose"][:, 3:], p.motion[:, 50:53])  # then jaw


def test_listing_is_lazy_and_clip_errors_name_the_file(tmp_path):
    clips = write_split(tmp_path)
    bad = tmp_path / f"{clips[1].clip_id}_speaker2.npz"
    bad.write_bytes(b"not a zip")
    source = open_split(tmp_path, "test")  # opening reads no file contents
    assert len(source) == 2
    source.load(clips[0].clip_id)
    with pytest.raises(InputError, match=bad.name):
        source.load(clips[1].clip_id)


def test_missing_partner_is_reported(tmp_path, capsys):
    clips = write_split(tmp_path)
    missing = tmp_path / f"{clips[0].clip_id}_speaker2.npz"
    missing.unlink()
    source = open_split(tmp_path, "test")
    assert source.clip_ids() == [clips[1].clip_id]
    assert missing.name in capsys.readouterr().err
    with pytest.raises(InputError, match=f"missing {missing.name}"):
        source.load(clips[0].clip_id)
    report = validate_folder(tmp_path, progress=False)
    assert not report.ok and len(report.errors) == 1 and str(missing) in report.errors[0]


def _rewrite_npz(path: Path, **change):
    with np.load(path) as npz:
        arrays = {k: npz[k] for k in npz.files}
    arrays.update(change)
    arrays = {k: v for k, v in arrays.items() if v is not None}
    np.savez(path, **arrays)


@pytest.mark.parametrize("change, message", [
    ({"exp": None}, "missing key"),
    ({"pose": np.zeros((75, 5), np.float32)}, "pose has shape"),
    ({"exp": np.full((75, 50), np.nan, np.float32)}, "NaN"),
    ({"exp": np.zeros((75, 50), np.int64)}, "dtype"),
])
def test_bad_npz_gives_clear_errors(tmp_path, change, message):
    clip = write_split(tmp_path, n=1)[0]
    path = tmp_path / f"{clip.clip_id}_speaker1.npz"
    _rewrite_npz(path, **change)
    report = validate_folder(tmp_path, progress=False)
    assert not report.ok
    assert any(str(path) in e and message in e for e in report.errors), report.errors
    with pytest.raises(InputError, match=path.name):
        open_split(tmp_path, "test").load(clip.clip_id)


def test_truncated_wav(tmp_path):
    clip = write_split(tmp_path, n=1)[0]
    path = tmp_path / f"{clip.clip_id}_speaker2.wav"
    path.write_bytes(path.read_bytes()[:20_000])
    with pytest.raises(InputError, match=f"{path.name}.*truncated"):
        read_wav(path)
    report = validate_folder(tmp_path, progress=False)
    assert any(str(path) in e and "truncated" in e for e in report.errors)


def test_wrong_sample_rate_and_stereo(tmp_path):
    clip = write_split(tmp_path, n=1)[0]
    path = tmp_path / f"{clip.clip_id}_speaker1.wav"
    write_wav(path, clip.participants[0].audio[::2], sample_rate=8000)
    with pytest.raises(InputError, match=f"{path.name}.*16000 Hz.*8000 Hz"):
        open_split(tmp_path, "test").load(clip.clip_id)
    assert any(str(path) in e and "8000 Hz" in e for e in validate_folder(tmp_path, progress=False).errors)
    data = wav_bytes(np.zeros(100, np.float32))
    stereo = data[:22] + struct.pack("<H", 2) + data[24:32] + struct.pack("<H", 4) + data[34:]
    path.write_bytes(stereo)
    with pytest.raises(InputError, match="mono"):
        read_wav(path)


def test_duration_mismatch_beyond_tolerance(tmp_path):
    clip = write_split(tmp_path, n=1)[0]
    path = tmp_path / f"{clip.clip_id}_speaker1.wav"
    write_wav(path, clip.participants[0].audio[: -16_000 // 2])  # half a second short
    with pytest.raises(InputError, match=f"{path.name}.*audio lasts"):
        open_split(tmp_path, "test").load(clip.clip_id)
    assert any("allowed difference" in e for e in validate_folder(tmp_path, progress=False).errors)


def test_small_duration_difference_is_padded(tmp_path):
    clip = write_split(tmp_path, n=1)[0]
    audio = clip.participants[0].audio
    write_wav(tmp_path / f"{clip.clip_id}_speaker1.wav", audio[:-700])  # about one frame short, like the release
    back = open_split(tmp_path, "test").load(clip.clip_id).participants[0].audio
    assert len(back) == len(audio)
    assert np.array_equal(back[:-700], audio[:-700]) and not back[-700:].any()


def float32_wav(audio: np.ndarray) -> bytes:
    """A 32-bit IEEE-float mono 16 kHz WAV, the encoding of the DualTalk release."""
    data = np.asarray(audio, dtype="<f4").tobytes()
    return struct.pack("<4sI4s4sIHHIIHH4sI", b"RIFF", 36 + len(data), b"WAVE", b"fmt ", 16, 3, 1, 16000,
                       64000, 4, 32, b"data", len(data)) + data


def test_float32_wav_like_the_release(tmp_path):
    audio = (np.sin(np.arange(1600) / 5.0) * 0.5).astype(np.float32)
    (tmp_path / "f.wav").write_bytes(float32_wav(audio))
    assert np.array_equal(read_wav(tmp_path / "f.wav"), audio)
    (tmp_path / "p.wav").write_bytes(wav_bytes(audio))
    assert np.abs(read_wav(tmp_path / "p.wav") - audio).max() <= 1 / 32768


def test_nan_in_a_float_wav(tmp_path):
    clip = write_split(tmp_path, n=1)[0]
    audio = clip.participants[1].audio.copy()
    audio[1000] = np.nan
    path = tmp_path / f"{clip.clip_id}_speaker2.wav"
    path.write_bytes(float32_wav(audio))
    assert any(str(path) in e and "non-finite" in e for e in validate_folder(tmp_path, progress=False).errors)
    with pytest.raises(InputError, match=f"{path.name}.*non-finite"):
        open_split(tmp_path, "test").load(clip.clip_id)


@settings(max_examples=40, deadline=None)
@given(arrays(np.float32, st.integers(0, 300), elements=st.floats(-1.0, 1.0, width=32)))
def test_wav_round_trip_is_within_half_a_step_and_exact_on_the_grid(tmp_path_factory, audio):
    path = tmp_path_factory.mktemp("wav") / "x.wav"
    write_wav(path, audio)
    back = read_wav(path)
    assert back.shape == audio.shape and back.dtype == np.float32
    assert np.all(np.abs(back - np.clip(audio, -1.0, 32767 / 32768)) <= 0.5 / 32768 + 1e-9)
    write_wav(path, back)
    assert np.array_equal(read_wav(path), back)  # samples on the 16-bit grid survive exactly


def test_not_a_dualtalk_folder(tmp_path):
    with pytest.raises(InputError, match="speaker1"):
        open_split(tmp_path, "test")
    with pytest.raises(InputError, match="not found"):
        open_split(tmp_path / "absent", "test")


def test_folder_info_counts(tmp_path):
    clips = write_split(tmp_path / "test", n=2, seconds=8.0)
    info = folder_info(tmp_path, progress=False)["splits"]["test"]
    assert info["dialogues"] == info["complete"] == 2
    assert info["frames"] == sum(c.num_frames for c in clips) == 400
    assert info["hours"] == pytest.approx(16.0 / 3600)
    assert info["turns"]["total"] >= 2
    assert set(info["motion_statistics_mean"]) == set(REAL_CLIPS)
    assert info["motion_statistics_mean"]["head_std"] == pytest.approx(
        np.mean([motion_statistics(p.motion)["head_std"] for c in clips for p in c.participants]), rel=1e-6)


@needs_demo
def test_real_demo_folder_lacks_one_npz_per_dialogue():
    report = validate_folder(DEMO, progress=False)
    assert report.checked == 2 and not report.warnings
    assert sorted(Path(e.split(": ")[0]).name for e in report.errors) == [
        "UbjUDM1MiGE_sub_video_72_speaker1.npz", "xkHwlcDSOjc_sub_video_109_000_speaker2.npz"]
    source = DualTalkSource(DEMO, "demo")
    assert source.clip_ids() == [] and len(source.incomplete) == 2
    with pytest.raises(InputError, match="UbjUDM1MiGE_sub_video_72_speaker1.npz"):
        source.load("UbjUDM1MiGE_sub_video_72")


@needs_demo
def test_calibration_statistics_reproduce_the_real_clips():
    """motion_statistics on the two real clips gives the published calibration table."""
    for k, stem in enumerate(["UbjUDM1MiGE_sub_video_72_speaker2", "xkHwlcDSOjc_sub_video_109_000_speaker1"]):
        stats = motion_statistics(load_gt_npz(DEMO / f"{stem}.npz"), read_wav(DEMO / f"{stem}.wav"))
        for name, values in REAL_CLIPS.items():
            tol = 0.05 if name == "jaw_speech_r" else 0.03 * values[k] + 5e-4  # table: 2 significant digits
            assert abs(stats[name] - values[k]) <= tol, (stem, name, stats[name], values[k])
