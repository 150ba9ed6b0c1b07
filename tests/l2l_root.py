"""A small synthetic split pair (train, test) in the Learning2Listen layout, shared by the L2L tests."""

from __future__ import annotations

import pytest

from dyadbench.synth.l2l_writer import write_l2l_split


@pytest.fixture(scope="session")
def l2l_train_test(tmp_path_factory):
    """Root holding synth/train (3 dialogues) and synth/test (2 dialogues), written once per session."""
    root = tmp_path_factory.mktemp("l2l-train-test")
    write_l2l_split(root, split="train", clips=3, seed=0, progress=False)
    write_l2l_split(root, split="test", clips=2, seed=0, progress=False)
    return root
