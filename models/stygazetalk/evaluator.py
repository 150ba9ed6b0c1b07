"""The frozen style encoder as the evaluator of the gaze suite's style cosine error (spec §4.6, D39).

Like an FID network, the evaluator is one fixed file: the shipped tiny SE-64
(``weights/style-encoder-tiny-se64.pt``), identified by its sha256 digest and :data:`EVALUATOR_VERSION`.
CE values are comparable only between results that record the same digest. It implements the
``dyadbench.metrics.gaze.StyleEncoder`` hook: windows (B, M, 7) in degrees → embeddings (B, d_s).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from dyadbench.training.checkpoint import file_digest
from models.stygazetalk.checkpoints import SHIPPED_STYLE_ENCODER, load_style_model
from models.stygazetalk.train_style import StyleModel

EVALUATOR_VERSION = "stygazetalk-se64-tiny-v2"  # v2: D47 inputs (centred angles + velocities), retrained


@dataclass
class StyleEvaluator:
    """Callable style encoder with ``digest``, ``window`` (M) and ``hop`` (N, D39) for the gaze suite."""

    model: StyleModel
    path: Path
    digest: str
    version: str
    window: int
    hop: int

    def __call__(self, windows: np.ndarray) -> np.ndarray:
        return self.model.embed_degrees(windows)


def load_style_evaluator(path: str | Path | None = None, hop: int = 25) -> StyleEvaluator:
    """The shipped evaluator (default) or a stage-1 checkpoint at ``path``."""
    path = Path(path) if path is not None else SHIPPED_STYLE_ENCODER
    model, _ = load_style_model(path)
    digest = file_digest(path)
    version = EVALUATOR_VERSION if path == SHIPPED_STYLE_ENCODER else f"{model.cfg.name}@{digest[:12]}"
    return StyleEvaluator(model, path, digest, version, model.cfg.window, hop)
