"""Synthetic splits on disk: byte-for-byte determinism, and the cached default corpus."""

import hashlib
from pathlib import Path

import numpy as np
import pytest

from dyadbench.datasets import synthetic
from dyadbench.datasets.dualtalk import validate_folder
from dyadbench.errors import InputError
from dyadbench.synth import writers
from dyadbench.synth.corpus import make_clip


def digests(folder: Path) -> dict[str, str]:
    return {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in sorted(folder.iterdir())}


def test_byte_for_byte_deterministic_for_a_seed_and_independent_of_jobs(tmp_path):
    a = writers.write_dualtalk_split(tmp_path / "a", split="ood", clips=2, seed=7, jobs=1, progress=False)
    writers.write_dualtalk_split(tmp_path / "b", split="ood", clips=2, seed=7, jobs=2, progress=False)
    writers.write_dualtalk_split(tmp_path / "c", split="ood", clips=2, seed=8, jobs=1, progress=False)
    first = digests(tmp_path / "a" / "ood")
    assert len(first) == 2 * 4 + 2  # 4 files per dialogue, synthetic.json and the output marker
    assert first == digests(tmp_path / "b" / "ood")
    other = digests(tmp_path / "c" / "ood")
    assert all(first[k] != other[k] for k in first if k.endswith((".wav", ".npz")))
    assert a["clips"] == 2 and a["seed"] == 7 and a["style_pool"] == "unseen"
    assert validate_folder(tmp_path / "a", progress=False).ok


@pytest.fixture
def small_corpus(tmp_path, monkeypatch):
    monkeypatch.setenv("DYADBENCH_CACHE", str(tmp_path / "cache"))
    monkeypatch.setitem(writers.SPLIT_SIZES, "val", 2)
    return tmp_path / "cache"


def test_default_corpus_generated_once_into_the_cache(small_corpus, capsys):
    source = synthetic.open_split(None, "val")
    err = capsys.readouterr().err
    folder = synthetic.corpus_root() / "val"
    assert "generating the synthetic val split" in err and str(folder) in err
    assert source.root == folder and folder.is_relative_to(small_corpus)
    assert [p.name for p in folder.parent.iterdir()] == ["val"]  # no temporary folder left behind
    marker = (folder / writers.MARKER).stat().st_mtime_ns
    again = synthetic.open_split(None, "val")
    err = capsys.readouterr().err
    assert "generating" not in err and "using the synthetic val split" in err
    assert (folder / writers.MARKER).stat().st_mtime_ns == marker and again.clip_ids() == source.clip_ids()


def test_default_corpus_round_trips_generator_annotations(small_corpus):
    source = synthetic.open_split(None, "val")
    clip = source.load(source.clip_ids()[1])
    original = make_clip("val", 1, seed=synthetic.DEFAULT_SEED)
    assert clip.clip_id == original.clip_id and clip.meta["speaking_source"] == "generator"
    for p, q in zip(original.participants, clip.participants):
        assert p.identity == q.identity
        assert np.array_equal(p.motion, q.motion) and np.array_equal(p.audio, q.audio)
        assert np.array_equal(original.meta["speaking"][p.name], clip.meta["speaking"][q.name])
    assert [tuple(t) for t in original.meta["turns"]] == clip.meta["turns"]
    for who, events in original.meta["events"].items():
        for kind, times in events.items():
            assert np.array_equal(times, clip.meta["events"][who][kind])


def test_split_from_other_generator_code_is_regenerated(small_corpus, capsys):
    source = synthetic.open_split(None, "val")
    marker_path = source.root / writers.MARKER
    marker_path.write_text(marker_path.read_text().replace(writers.generator_digest(), "older-code"))
    capsys.readouterr()
    synthetic.open_split(None, "val")
    assert "made by other generator code" in capsys.readouterr().err
    assert writers.generator_digest() in marker_path.read_text()


def test_a_folder_not_written_by_the_generator_is_never_replaced(small_corpus):
    folder = synthetic.corpus_root() / "val"
    folder.mkdir(parents=True)
    (folder / "real_clip_speaker1.wav").write_bytes(b"someone's data")
    with pytest.raises(InputError, match="refusing to overwrite"):
        synthetic.open_split(None, "val")
    assert (folder / "real_clip_speaker1.wav").read_bytes() == b"someone's data"
    folder.joinpath("real_clip_speaker1.wav").unlink()
    assert len(synthetic.open_split(None, "val")) == 2  # an empty folder is filled
