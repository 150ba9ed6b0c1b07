"""``build_stygazetalk``: the registered factory of the ``stygazetalk`` model (gaze7 layout, streaming).

- Weights: ``options.weights`` (a stage-2 checkpoint) or the shipped tiny SE-64 checkpoint.
- Style transfer: ``options.extra["style_from"]`` — a reference session's motion (T, 7) in degrees,
  or the path of a gaze-layout session ``.npz`` (key ``motion``). Its style vector (mean SE embedding
  over its windows) replaces SE(last M frames) in every window.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from dyadbench.errors import InputError
from dyadbench.protocol.interface import ModelInfo, ModelOptions
from models.stygazetalk.checkpoints import SHIPPED_MODEL, load_system
from models.stygazetalk.stream import StyGazeTalkStream

VERSION = "1"


def build_stygazetalk(options: ModelOptions) -> StyGazeTalkStream:
    path = Path(options.weights) if options.weights is not None else SHIPPED_MODEL
    system, meta = load_system(path)
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
    if isinstance(style_from, np.ndarray):
        motion, desc = style_from, f"array of {style_from.shape[0]} frames"
    else:
        path = Path(str(style_from))
        if not path.is_file():
            raise InputError(path, "style reference session not found (give a gaze-layout .npz)")
        with np.load(path, allow_pickle=False) as data:
            if "motion" not in data:
                raise InputError(path, "style reference has no 'motion' array")
            motion, desc = data["motion"], str(path)
    motion = np.asarray(motion, dtype=np.float32)
    if motion.ndim != 2 or motion.shape[1] != 7 or not np.isfinite(motion).all():
        raise InputError(desc, f"style reference motion must be finite (T, 7) degrees, got {motion.shape}")
    return motion, desc
