"""Shipped tiny checkpoints per embedded corpus (dyadbench.shipped): each is committed, was trained on the
corpus whose runs load it, and a run on that corpus picks it when no --weights is given."""

from pathlib import Path

import pytest
import torch

from dyadbench.protocol.interface import ModelOptions
from dyadbench.registry import DEFAULT_EMBEDDED
from dyadbench.shipped import shipped_checkpoint
from models.dualtalk.registry import build_dualtalk
from models.dualtalk.registry import shipped as dualtalk_shipped
from models.sfms.registry import shipped as sfms_shipped
from models.timar.registry import shipped as timar_shipped

# (what, path) of every checkpoint the package ships, per corpus.
SHIPPED = {
    "synthetic": [("timar", timar_shipped("timar", "synthetic")),
                  ("timar-stream", timar_shipped("timar-stream", "synthetic")),
                  ("sfms", sfms_shipped("synthetic")), ("dualtalk", dualtalk_shipped("synthetic"))],
    "synthetic-v2": [("timar", timar_shipped("timar", "synthetic-v2")),
                     ("timar-stream", timar_shipped("timar-stream", "synthetic-v2")), ("sfms", sfms_shipped("synthetic-v2")),
                     ("dualtalk", dualtalk_shipped("synthetic-v2"))],
}


@pytest.mark.parametrize("corpus,what,path", [(c, w, p) for c, rows in SHIPPED.items() for w, p in rows])
def test_each_shipped_checkpoint_is_committed_small_and_trained_on_its_corpus(corpus, what, path):
    assert path.is_file(), f"committed checkpoint {path} is missing (see README for the command that trains it)"
    assert path.stat().st_size < 8 * 2**20
    meta = torch.load(path, map_location="cpu", weights_only=True)["meta"]
    assert meta["data"]["dataset"] == corpus and meta["data"]["split"] == "train"
    assert meta["model"] == what


def test_checkpoint_names_follow_the_corpus(tmp_path):
    assert shipped_checkpoint(tmp_path, "m", "synthetic") == tmp_path / "m.pt"
    assert shipped_checkpoint(tmp_path, "m", "synthetic-v2") == tmp_path / "m-v2.pt"
    # real data and code that names no dataset: the default corpus's checkpoint
    default = shipped_checkpoint(tmp_path, "m", DEFAULT_EMBEDDED)
    assert shipped_checkpoint(tmp_path, "m", "dualtalk") == default == shipped_checkpoint(tmp_path, "m", None)
    assert default == tmp_path / "m-v2.pt"  # corpus v2 is the default (every model has its v2 checkpoint)


def test_a_run_loads_the_checkpoint_of_the_corpus_it_evaluates():
    for corpus in ("synthetic", "synthetic-v2"):
        info = build_dualtalk(ModelOptions(dataset=corpus)).info
        assert Path(info.weights_path) == dualtalk_shipped(corpus)
    assert (build_dualtalk(ModelOptions(dataset="synthetic")).info.weights_digest
            != build_dualtalk(ModelOptions(dataset="synthetic-v2")).info.weights_digest)
