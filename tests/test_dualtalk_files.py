"""DualTalk ground-truth npz and prediction npy: pose-half swap, round trip, and clear errors."""

import pickle
from pathlib import Path

import numpy as np
import pytest

from dyadbench.datasets.dualtalk_files import load_gt_npz, load_prediction, write_gt_npz
from dyadbench.errors import InputError

DEMO = Path("/work/shared/data/dualtalk-demo")
DEMO_FILES = sorted(DEMO.glob("*.npz")) if DEMO.is_dir() else []


def _motion(t=30, seed=0):
    return np.random.default_rng(seed).normal(size=(t, 56))


def test_swap_puts_jaw_before_head_rotation(tmp_path):
    t = 4
    exp = np.full((t, 50), 1.0, np.float32)
    pose = np.concatenate([np.full((t, 3), 2.0), np.full((t, 3), 3.0)], axis=1).astype(np.float32)
    np.savez(tmp_path / "a.npz", exp=exp, pose=pose)
    m = load_gt_npz(tmp_path / "a.npz")
    assert m.shape == (t, 56) and m.dtype == np.float64
    assert (m[:, :50] == 1).all()
    assert (m[:, 50:53] == 3).all()  # jaw = pose[:, 3:6]
    assert (m[:, 53:56] == 2).all()  # head rotation = pose[:, 0:3]


def test_write_then_load_round_trip(tmp_path):
    m = _motion().astype(np.float32).astype(np.float64)
    shape = np.zeros((30, 100), np.float32)
    write_gt_npz(tmp_path / "g.npz", m, extra={"shape": shape})
    stored = np.load(tmp_path / "g.npz")
    assert sorted(stored.files) == ["exp", "pose", "shape"]
    assert stored["exp"].dtype == np.float32 and stored["pose"].shape == (30, 6)
    np.testing.assert_array_equal(stored["pose"][:, :3], m[:, 53:56])  # rotation first on disk
    np.testing.assert_array_equal(load_gt_npz(tmp_path / "g.npz"), m)


def test_write_rejects_extra_named_like_motion(tmp_path):
    with pytest.raises(InputError, match="exp"):
        write_gt_npz(tmp_path / "g.npz", _motion(), extra={"exp": np.zeros(3)})


@pytest.mark.skipif(not DEMO_FILES, reason="DualTalk demo clips not available")
@pytest.mark.parametrize("path", DEMO_FILES, ids=lambda p: p.name)
def test_real_dualtalk_files(path):
    raw = np.load(path)
    m = load_gt_npz(path)
    assert m.shape == (raw["exp"].shape[0], 56)
    np.testing.assert_array_equal(m[:, 50:53], raw["pose"][:, 3:6])
    np.testing.assert_array_equal(m[:, 53:56], raw["pose"][:, 0:3])
    # Calibration facts: head rotation per-axis std ~0.03-0.1 rad, expression std of order 0.5.
    assert 0.01 < m[:, 53:56].std(axis=0).mean() < 0.2
    assert 0.2 < m[:, :50].std(axis=0).mean() < 1.0


def _write(tmp_path, name="g.npz", **arrays):
    path = tmp_path / name
    np.savez(path, **arrays)
    return path


GOOD = {"exp": np.zeros((5, 50), np.float32), "pose": np.zeros((5, 6), np.float32)}


@pytest.mark.parametrize("arrays, message", [
    ({"exp": GOOD["exp"]}, "missing key"),
    ({"exp": np.zeros((5, 49), np.float32), "pose": GOOD["pose"]}, "50 values per frame"),
    ({"exp": GOOD["exp"], "pose": np.zeros((5, 3), np.float32)}, "6 values per frame"),
    ({"exp": np.zeros(5, np.float32), "pose": GOOD["pose"]}, "2-d"),
    ({"exp": GOOD["exp"], "pose": np.zeros((4, 6), np.float32)}, "5 frames but pose has 4"),
    ({"exp": np.zeros((5, 50), np.int32), "pose": GOOD["pose"]}, "floating-point"),
    ({"exp": np.full((5, 50), np.nan, np.float32), "pose": GOOD["pose"]}, "NaN/inf"),
    ({"exp": np.zeros((0, 50), np.float32), "pose": np.zeros((0, 6), np.float32)}, "no frames"),
])
def test_bad_ground_truth_is_named(tmp_path, arrays, message):
    path = _write(tmp_path, **arrays)
    with pytest.raises(InputError, match=message) as err:
        load_gt_npz(path)
    assert str(path) in str(err.value)


def test_missing_file(tmp_path):
    with pytest.raises(InputError, match="not found") as err:
        load_gt_npz(tmp_path / "nope.npz")
    assert "nope.npz" in str(err.value)


def test_pickled_npz_is_refused(tmp_path):
    path = tmp_path / "p.npz"
    np.savez(path, exp=np.array([{"a": 1}], dtype=object), pose=GOOD["pose"])
    with pytest.raises(InputError, match="pickled") as err:
        load_gt_npz(path)
    assert "p.npz" in str(err.value)


@pytest.mark.parametrize("content", [b"not a zip", pickle.dumps({"exp": 1})])
def test_unreadable_npz(tmp_path, content):
    path = tmp_path / "bad.npz"
    path.write_bytes(content)
    with pytest.raises(InputError) as err:
        load_gt_npz(path)
    assert "bad.npz" in str(err.value)


def test_npy_given_as_ground_truth(tmp_path):
    path = tmp_path / "a.npz"
    with open(path, "wb") as f:
        np.save(f, np.zeros((5, 56)))
    with pytest.raises(InputError, match="expected an .npz archive"):
        load_gt_npz(path)


def test_load_prediction(tmp_path):
    m = _motion(12).astype(np.float32)
    np.save(tmp_path / "c_speaker1.npy", m)
    out = load_prediction(tmp_path / "c_speaker1.npy")
    assert out.dtype == np.float64
    np.testing.assert_array_equal(out, m)


def test_load_prediction_errors(tmp_path):
    np.save(tmp_path / "w.npy", np.zeros((5, 55)))
    with pytest.raises(InputError, match="56 values per frame"):
        load_prediction(tmp_path / "w.npy")
    bad = np.zeros((5, 56))
    bad[2, 3] = np.inf
    np.save(tmp_path / "n.npy", bad)
    with pytest.raises(InputError, match="1 NaN/inf"):
        load_prediction(tmp_path / "n.npy")
    assert np.isinf(load_prediction(tmp_path / "n.npy", finite=False)).sum() == 1
    np.save(tmp_path / "o.npy", np.array([None, 1], dtype=object), allow_pickle=True)
    with pytest.raises(InputError, match="pickled"):
        load_prediction(tmp_path / "o.npy")
