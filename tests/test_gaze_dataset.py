"""The gaze–head session layout: writing, reading back, the ±40° rule, validation and bad folders."""

import re

import numpy as np
import pytest

from dyadbench import atomic
from dyadbench.datasets import gaze as gz
from dyadbench.datasets.layouts import get_layout
from dyadbench.datasets.synthetic_gaze import open_synthetic_split
from dyadbench.datasets.wav import write_wav
from dyadbench.errors import ConfigError, InputError
from dyadbench.synth.gaze import make_gaze_sessions
from dyadbench.synth.gaze_writer import update_index, write_gaze_split


@pytest.fixture(scope="module")
def root(tmp_path_factory):
    out = tmp_path_factory.mktemp("gaze")
    write_gaze_split(out, split="test", clips=3, seed=3, duration_s=8)
    write_gaze_split(out, split="train", clips=2, seed=3, duration_s=8)
    return out


def test_round_trip_is_exact(root):
    clips = make_gaze_sessions("test", 3, seed=3, duration_s=8)
    source = gz.open_split(root, "test")
    assert source.clip_ids() == [c.clip_id for c in clips]
    for clip in clips:
        back = source.load(clip.clip_id)
        p, q = clip.participants[0], back.participants[0]
        assert back.layout == "gaze7" and back.fps == 25.0 and back.sample_rate == 16_000
        assert q.name == "subject" and q.identity == p.identity
        np.testing.assert_array_equal(q.motion, p.motion)
        np.testing.assert_array_equal(q.audio, p.audio)  # the synthetic speech sits on the PCM16 grid
        np.testing.assert_array_equal(back.meta["speaking"]["subject"], clip.meta["speaking"]["subject"])


def test_split_folder_and_index(root):
    assert gz.open_split(root / "train", None).clip_ids() == gz.open_split(root, "train").clip_ids()
    rows = gz.read_index(root)
    assert {r["split"] for r in rows} == {"test", "train"} and len(rows) == 5
    with pytest.raises(InputError, match="no session in split 'val'"):
        gz.open_split(root, "val")
    with pytest.raises(ConfigError):
        gz.open_split(None, "test")


def test_validate_and_describe_through_the_layout_registry(root):
    layout = get_layout("gaze")
    report = layout.validate(root)
    assert report.ok and report.checked == 5, report.summary()
    info = layout.describe(root)
    assert info["splits"]["test"]["sessions"] == 3 and info["splits"]["test"]["frames"] == 3 * 200
    assert info["splits"]["train"]["speakers"] == ["spk1", "spk2"]


def write_session(folder, name, motion, *, speaker="a", seconds=None, rate=16_000, extra=None):
    folder.mkdir(parents=True, exist_ok=True)
    atomic.save_npz(folder / f"{name}.npz", motion=np.asarray(motion, np.float32), fps=np.float64(25.0),
                    speaker=np.str_(speaker), **(extra or {}))
    n = int((len(motion) / 25.0 if seconds is None else seconds) * rate)
    write_wav(folder / f"{name}.wav", np.zeros(n, np.float32), rate)


def make_root(tmp_path, sessions):
    """sessions: name -> (motion, kwargs); all in split test."""
    for name, (motion, kw) in sessions.items():
        write_session(tmp_path / "test", name, motion, **kw)
    update_index(tmp_path, "test", [(n, kw.get("speaker", "a")) for n, (m, kw) in sessions.items()])
    return tmp_path


def test_out_of_range_frames_cut_the_session(tmp_path):
    motion = np.zeros((300, 7))
    motion[100, 4] = 45.0  # beyond +-40 deg: dropped, the session is cut there
    motion[250:260, 0] = -41.0  # leaves a 40-frame tail, shorter than 75 frames: discarded
    root = make_root(tmp_path, {"s1": (motion, {})})
    source = gz.open_split(root, "test")
    assert source.clip_ids() == ["s1-f000000", "s1-f000101"]
    assert [source.load(c).num_frames for c in source.clip_ids()] == [100, 149]
    second = source.load("s1-f000101")
    assert second.meta["first_frame"] == 101 and len(second.participants[0].audio) == 149 * 640
    info = source.describe()
    assert info["dropped_frames"] == 11 and info["discarded_segments"] == 1
    report = gz.validate_folder(root)
    assert report.ok and any("11 of 300 frames will be dropped" in w for w in report.warnings)


def test_valid_mask_drops_frames(tmp_path):
    valid = np.ones(200, bool)
    valid[:20] = False
    root = make_root(tmp_path, {"s1": (np.zeros((200, 7)), {"extra": {"valid": valid}})})
    assert gz.open_split(root, "test").clip_ids() == ["s1-f000020"]


@pytest.mark.parametrize("mutate, message", [
    (lambda f: (f / "splits.csv").unlink(), "splits.csv"),
    (lambda f: write_session(f / "test", "s1", np.zeros((100, 6))), "expected 7 values per frame"),
    (lambda f: atomic.save_npz(f / "test" / "s1.npz", motion=np.zeros((100, 7), np.float32)), "missing key 'fps'"),
    (lambda f: write_session(f / "test", "s1", np.zeros((100, 7)), speaker="b"), "differs from splits.csv"),
    (lambda f: write_session(f / "test", "s1", np.zeros((100, 7)), seconds=2.0), "must match within one frame"),
    (lambda f: write_session(f / "test", "s1", np.zeros((100, 7)), rate=8000), "expected 16000 Hz"),
    (lambda f: (f / "test" / "s1.wav").unlink(), "s1.wav: file not found"),
    (lambda f: np.savez(f / "test" / "s1.npz", motion=np.zeros((100, 7)), fps=25.0,
                        speaker=np.array(["a"], dtype=object)), "pickled"),
    (lambda f: write_session(f / "test", "s1", np.zeros((100, 7)), extra={"speaking": np.zeros(99, bool)}),
     "[speaking]: must be bool (100,)"),
])
def test_bad_folders_give_named_errors(tmp_path, mutate, message):
    root = make_root(tmp_path, {"s1": (np.zeros((100, 7)), {})})
    mutate(root)
    report = gz.validate_folder(root)
    assert not report.ok
    assert any(message in e for e in report.errors), report.errors
    with pytest.raises(InputError, match=re.escape(message)):
        source = gz.open_split(root, "test")
        for clip in source:
            pass


def test_session_without_any_usable_run(tmp_path):
    root = make_root(tmp_path, {"s1": (np.full((100, 7), 50.0), {})})
    assert any("no run of 75 usable frames" in e for e in gz.validate_folder(root).errors)
    assert gz.open_split(root, "test").clip_ids() == []


def test_synthetic_split_is_generated_once_into_the_cache(tmp_path, monkeypatch):
    monkeypatch.setattr("dyadbench.synth.gaze.DEFAULT_SESSIONS", {"ood": 2})
    monkeypatch.setattr("dyadbench.synth.gaze.DEFAULT_DURATION_S", 6.0)
    monkeypatch.setenv("DYADBENCH_CACHE", str(tmp_path))
    source = open_synthetic_split(None, "ood")
    assert source.dataset == "synthetic-gaze" and str(source.root).startswith(str(tmp_path))
    assert source.clip_ids() == ["ood000_ood1", "ood001_ood2"]
    marker = source.root / "ood" / ".complete.json"
    stamp = marker.stat().st_mtime_ns
    again = open_synthetic_split(None, "ood")
    assert again.clip_ids() == source.clip_ids() and marker.stat().st_mtime_ns == stamp
    with pytest.raises(ConfigError, match="unknown synthetic gaze split"):
        open_synthetic_split(None, "dev")
