"""The committed paper-size StyGazeTalk pair and its comparison with the tiny one
(benchmarks/bench_stygazetalk_paper_size.py): the files have the spec's sizes and were trained as recorded,
the generator names its own style encoder, and the committed result was computed from exactly these files
(retraining either checkpoint without re-running the benchmark fails here)."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import click
import pytest
import torch

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))

import bench_stygazetalk_paper_size as bench  # noqa: E402
from dyadbench.training.checkpoint import file_digest  # noqa: E402
from models.stygazetalk.checkpoints import (PAPER_SIZE_MODEL, PAPER_SIZE_STYLE_ENCODER, SHIPPED_MODEL,  # noqa: E402
                                            SHIPPED_STYLE_ENCODER, load_style_model, load_system)


def test_the_paper_size_pair_has_the_spec_sizes_and_full_schedules():
    system, meta = load_system(PAPER_SIZE_MODEL)
    lstms = [m for m in system.generator.modules() if isinstance(m, torch.nn.LSTM)]
    assert [(m.num_layers, m.hidden_size) for m in lstms] == [(3, 256)]  # spec D17
    assert meta["steps"] == 30_000 and system.cfg.name == "base-se64-vel-x1"
    assert meta["style_encoder_digest"] == file_digest(PAPER_SIZE_STYLE_ENCODER)
    style, style_meta = load_style_model(PAPER_SIZE_STYLE_ENCODER)
    blocks = [m for m in style.modules() if isinstance(m, torch.nn.TransformerEncoderLayer)]
    assert len(blocks) == 4 and style_meta["steps"] == 20_000  # spec D16
    # the frozen copy inside the generator file is the stage-1 encoder itself
    for name, tensor in style.encoder.state_dict().items():
        assert torch.equal(system.style_encoder.state_dict()[name], tensor), name


def test_the_committed_comparison_was_computed_from_the_committed_files():
    result = json.loads(bench.RESULT.with_suffix(".json").read_text())["data"]
    files = {"paper size": (PAPER_SIZE_MODEL, PAPER_SIZE_STYLE_ENCODER),
             "tiny (shipped)": (SHIPPED_MODEL, SHIPPED_STYLE_ENCODER)}
    for label, (generator, style) in files.items():
        recorded = result["checkpoints"][label]
        assert recorded["generator"]["sha256"] == file_digest(generator), label
        assert recorded["style_encoder"]["sha256"] == file_digest(style), label
    cells = {(r["split"], r["row"], r["decoding"]) for r in result["rows"]}
    for split in ("test", "ood"):
        for label in files:
            assert {(split, label, "own (X1 sampled eyes)"), (split, label, "mean")} <= cells


def test_a_generator_with_another_style_encoder_is_refused():
    generator = bench.record(PAPER_SIZE_MODEL, style=False)
    with pytest.raises(click.UsageError, match=r"--paper-style") as caught:
        bench.check_pair(generator, bench.record(SHIPPED_STYLE_ENCODER, style=True))
    assert str(PAPER_SIZE_MODEL) in caught.value.message and str(SHIPPED_STYLE_ENCODER) in caught.value.message
    bench.check_pair(generator, bench.record(PAPER_SIZE_STYLE_ENCODER, style=True))
