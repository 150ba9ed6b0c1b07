"""``build_stygazetalk``: the registered factory of the ``stygazetalk`` model (gaze7 layout, streaming).

- Weights: ``options.weights`` (a stage-2 checkpoint) or the shipped tiny SE-64-VEL checkpoint.
- Inference-only overrides of the checkpoint's config from ``options.extra``: ``seed_window``
  (``"gt"`` | ``"mpgw-sim"``, D30), ``decoding`` (``"mean"``: the paper's deterministic model |
  ``"sample"``: X1), ``sample_temperature``, ``sample_dims`` (``"gaze"`` | ``"all"``).
- Style transfer: ``options.extra["style_from"]`` — a reference session's motion (T, 7) in degrees,
  or the path of a gaze-layout session ``.npz`` (key ``motion``). Its style vector (mean SE embedding
  over its windows) replaces SE(last M frames) in every window.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np

from dyadbench.datasets.gaze import keep_mask, read_session
from dyadbench.errors import InputError
from dyadbench.protocol.interface import ModelInfo, ModelOptions
from models.stygazetalk.checkpoints import SHIPPED_MODEL, load_system
from models.stygazetalk.stream import StyGazeTalkStream

VERSION = "1"
INFERENCE_OVERRIDES = ("seed_window", "decoding", "sample_temperature", "sample_dims")


def build_stygazetalk(options: ModelOptions) -> StyGazeTalkStream:
    path = Path(options.weights) if options.weights is not None else SHIPPED_MODEL
    system, meta = load_system(path)
    overrides = {k: options.extra[k] for k in INFERENCE_OVERRIDES if k in options.extra}
    if overrides:  # inference-only settings, e.g. the MPGW-sim seed or sampled decoding with these weights
        system.cfg = replace(system.cfg, **overrides).validate()
    style_from = options.extra.get("style_from")
    style, style_desc = None, None
    if style_from is not None:
        motion, style_desc = _reference_motion(style_from)
        style = system.reference_style(motion)
    info = ModelInfo(
        name="stygazetalk", layout="gaze7", version=VERSION, weights_digest=meta["digest"],
        weights_path=meta["path"], seed_frames=system.cfg.window,
        config={"generator": system.cfg.to_dict(),
                "style_encoder": system.se_cfg.to_dict() if system.se_cfg is not None else None,
                "style_encoder_digest": meta.get("style_encoder_digest"),
                "seed_window": f"first {system.cfg.window} ground-truth frames of the agent "
                               f"({system.cfg.seed_window}); excluded from scores",
                "motion_history": "own outputs, kept by the model",
                "style_from": style_desc})
    return StyGazeTalkStream(system, info, style=style, run_seed=options.seed)


def _reference_motion(style_from: object) -> tuple[np.ndarray, str]:
    """(T, 7) degrees of a style reference: an array, or a gaze-layout session file (kept frames only)."""
    if isinstance(style_from, np.ndarray):
        motion, desc = style_from, f"array of {style_from.shape[0]} frames"
    else:
        path = Path(str(style_from))
        if not path.is_file():
            raise InputError(path, "style reference session not found (give a gaze-layout <session>.npz)")
        session = read_session(path)
        motion, desc = session.motion[keep_mask(session)], str(path)
    motion = np.asarray(motion, dtype=np.float32)
    if motion.ndim != 2 or motion.shape[1] != 7 or not np.isfinite(motion).all():
        raise InputError(desc, f"style reference motion must be finite (T, 7) degrees, got {motion.shape}")
    return motion, desc
