"""Generator v2 beside v1: v1 unchanged, v2 deterministic, v2 opened as dataset ``synthetic-v2`` from its own
cache folder with its own marker."""

import hashlib

import numpy as np
import pytest

from dyadbench.cli.eval import resolve_dataset
from dyadbench.datasets import synthetic
from dyadbench.registry import DATASETS
from dyadbench.synth import corpus, corpus_v2, writers, writers_v2
from dyadbench.synth.conversation import Dynamics
from tests.test_synth_writers import small_corpus  # noqa: F401  (a cache with 2-dialogue val splits)

# sha256 of (motion, audio) bytes of both speakers of two 8-s v1 clips (seed 0), recorded before v2 existed
V1_CLIPS = {("test", 0): "afe045ecb820e1b9096c4142e8cf33604554aab0a44601525929801f6f1ffde0",
            ("ood", 1): "1b6782eb59f55c16d51faf5f38d6c670e4c7072abe66ab77c0d01067cf875c49"}


def arrays_digest(clip):
    h = hashlib.sha256()
    for p in clip.participants:
        h.update(p.motion.tobytes())
        h.update(p.audio.tobytes())
    return h.hexdigest()


@pytest.mark.parametrize("split, index", list(V1_CLIPS))
def test_v1_clips_are_byte_identical_to_before_v2(split, index):
    assert arrays_digest(corpus.make_clip(split, index, seed=0, duration_s=8.0)) == V1_CLIPS[split, index]


def test_v2_is_deterministic_per_seed_and_subset_stable():
    a = corpus_v2.make_clips("test", 3, seed=4, duration_s=12.0)
    b = corpus_v2.make_clip("test", 2, seed=4, duration_s=12.0)
    assert arrays_digest(a[2]) == arrays_digest(b)
    assert np.array_equal(a[2].meta["conversation"]["mood"], b.meta["conversation"]["mood"])
    assert arrays_digest(corpus_v2.make_clip("test", 2, seed=5, duration_s=12.0)) != arrays_digest(b)
    assert arrays_digest(corpus.make_clip("test", 2, seed=4, duration_s=12.0)) != arrays_digest(b)


def test_switches_change_only_their_mechanism():
    on = corpus_v2.make_clip("test", 1, seed=2, duration_s=20.0)
    off = corpus_v2.make_clip("test", 1, seed=2, duration_s=20.0,
                              dynamics=Dynamics(mood=False, contagion=False, engagement=False, nod_excitation=False))
    assert on.meta["turns"] == off.meta["turns"]  # the conversation itself is the same
    assert not np.any(off.meta["conversation"]["mood"]) and np.any(on.meta["conversation"]["mood"])
    for p, q in zip(on.participants, off.participants):
        assert p.identity == q.identity
        assert np.array_equal(on.meta["speaking"][p.name], off.meta["speaking"][q.name])
        assert not np.array_equal(p.motion, q.motion)
    assert off.meta["generator"]["dynamics"] == {k: False for k in Dynamics().as_dict()}


def test_v2_opens_as_its_own_dataset_from_its_own_cache_folder(small_corpus, capsys):
    source = DATASETS.load("synthetic-v2")(None, "val")
    err = capsys.readouterr().err
    assert "generating the synthetic-v2 val split" in err
    assert source.root == small_corpus / "synthetic-v2" / "val" and source.dataset == "synthetic-v2"
    generated = source.generated_by()
    assert generated["version"] == 2 and generated["generator_digest"] == writers_v2.generator_digest()
    assert writers_v2.generator_digest() != writers.generator_digest()
    clip = source.load(source.clip_ids()[1])
    original = corpus_v2.make_clip("val", 1, seed=synthetic.DEFAULT_SEED)
    assert arrays_digest(clip) == arrays_digest(original)
    v1 = DATASETS.load("synthetic")(None, "val")  # v1 beside it, untouched
    assert v1.root == small_corpus / "synthetic-v1" / "val" and v1.generated_by()["version"] == 1
    assert arrays_digest(v1.load(v1.clip_ids()[1])) != arrays_digest(clip)
    capsys.readouterr()
    DATASETS.load("synthetic-v2")(None, "val")
    assert "generating" not in capsys.readouterr().err  # cached
    assert resolve_dataset(None, "synthetic-v2") == "synthetic-v2"  # eval/sweep take it without --data
