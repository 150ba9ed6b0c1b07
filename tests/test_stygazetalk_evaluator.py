"""The shipped frozen style encoder as the gaze suite's style-cosine-error evaluator (versioned, hashed)."""

from __future__ import annotations

import hashlib

import numpy as np
import pytest
import torch

from dyadbench.protocol.interface import ModelInfo
from dyadbench.protocol.runner import suite_options
from dyadbench.scoring.gaze import score_arrays
from dyadbench.scoring.report import ScoreItem
from dyadbench.synth.gaze import make_gaze_session
from models.stygazetalk.checkpoints import SHIPPED_STYLE_ENCODER, save_style_model
from models.stygazetalk.config import get_style_config
from models.stygazetalk.evaluator import EVALUATOR_VERSION, load_style_evaluator
from models.stygazetalk.train_style import StyleModel

torch.set_num_threads(1)

# `sha256sum models/stygazetalk/weights/style-encoder-tiny-se64.pt` of the file EVALUATOR_VERSION names:
# replacing the weights without a new version fails here.
SHIPPED_DIGEST = "5e21defb3377c0763369307841b9b854acf341ef94aa5c3d4a0a058b0c6ddc45"


def test_shipped_evaluator_is_versioned_by_its_digest():
    ev = load_style_evaluator()
    assert ev.path == SHIPPED_STYLE_ENCODER and ev.version == EVALUATOR_VERSION
    assert ev.digest == SHIPPED_DIGEST
    assert (ev.window, ev.hop) == (50, 25) and ev.model.cfg.d_s == 64
    assert not ev.model.training


def test_evaluator_is_deterministic_and_scores_zero_ce_on_ground_truth():
    ev = load_style_evaluator()
    clip = make_gaze_session("test", 1, seed=0, duration_s=8.0)
    p = clip.participants[0]
    windows = np.stack([p.motion[s:s + 50] for s in (50, 75, 100)]).astype(np.float64)
    assert np.array_equal(ev(windows), ev(windows))
    other = make_gaze_session("test", 2, seed=0, duration_s=8.0).participants[0].motion
    items = [ScoreItem("same_subject", p.motion, p.motion, audio=p.audio),
             ScoreItem("other_subject", other, p.motion, audio=p.audio)]
    report = score_arrays(items, seed=0, style_encoder=ev)
    ce = {row["clip"]: row["style_ce"] for row in report.per_item}
    assert ce["same_subject"] == pytest.approx(0.0, abs=1e-6)
    assert ce["other_subject"] > 0.01
    assert report.config["style_encoder"] == SHIPPED_DIGEST


def test_a_user_checkpoint_gets_a_digest_version(tmp_path):
    path = save_style_model(tmp_path / "se.pt", StyleModel(get_style_config("tiny-se32")), {})
    ev = load_style_evaluator(path, hop=10)
    digest = hashlib.sha256(path.read_bytes()).hexdigest()
    assert ev.version == f"tiny-se32@{digest[:12]}" and ev.hop == 10 and ev.digest == digest


@pytest.mark.parametrize("seed_frames,skip", [(0, 50), (75, 75)])
def test_a_models_gaze_run_scores_style_with_the_registered_evaluator(seed_frames, skip):
    # the runner asks the gaze suite (dyadbench.scoring.gaze.model_options), which loads the registry's
    # evaluator: the shipped file, and at least the suite's 50-frame seed window skipped
    options = suite_options("gaze", ModelInfo(name="m", layout="gaze7", seed_frames=seed_frames))
    assert options["style_encoder"].digest == SHIPPED_DIGEST and options["config"].skip_frames == skip
    assert suite_options("dualtalk", ModelInfo(name="m")) == {}
