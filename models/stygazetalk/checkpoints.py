"""StyGazeTalk checkpoint files (through :mod:`dyadbench.training.checkpoint`) and the shipped weights.

- Stage 1 (``model = "stygazetalk-style"``): the style encoder and the train-split motion statistics.
- Stage 2 (``model = "stygazetalk"``): the whole :class:`StyGazeTalkSystem` (normalisers, frozen
  style encoder, generator); ``meta["style_encoder_digest"]`` names the stage-1 file it was built on.

The shipped tiny checkpoints (and the paper-size pair) live in ``models/stygazetalk/weights/`` (package data).
"""

from __future__ import annotations

from pathlib import Path

from dyadbench.errors import InputError
from dyadbench.training.checkpoint import file_digest, load_checkpoint, save_checkpoint
from models.stygazetalk.config import GeneratorConfig, StyleEncoderConfig, config_from_dict
from models.stygazetalk.system import StyGazeTalkSystem
from models.stygazetalk.train_style import StyleModel

WEIGHTS_DIR = Path(__file__).resolve().parent / "weights"
SHIPPED_MODEL = WEIGHTS_DIR / "stygazetalk-tiny-se64-vel-x1.pt"  # SE-64-VEL weights, sampled eye decoding (X1)
SHIPPED_STYLE_ENCODER = WEIGHTS_DIR / "style-encoder-tiny-se64.pt"
# the paper's sizes (spec presets base-se64 / base-se64-vel-x1), kept for the paper-size comparison
PAPER_SIZE_MODEL = WEIGHTS_DIR / "stygazetalk-base-se64-vel-x1.pt"
PAPER_SIZE_STYLE_ENCODER = WEIGHTS_DIR / "style-encoder-base-se64.pt"
STYLE_MODEL_NAME = "stygazetalk-style"
MODEL_NAME = "stygazetalk"
REPRODUCE = ("dyadbench train stygazetalk-style --config tiny-se64 --export runs/sgt/se64.pt && "
             "dyadbench train stygazetalk --config tiny-se64-vel-x1 --style-encoder runs/sgt/se64.pt "
             "--export runs/sgt/tiny-se64-vel-x1.pt")


def save_style_model(path: str | Path, model: StyleModel, meta: dict) -> Path:
    return save_checkpoint(path, model_state=model.state_dict(), config={"style_encoder": model.cfg.to_dict()},
                           meta={"model": STYLE_MODEL_NAME, **meta})


def load_style_model(path: str | Path) -> tuple[StyleModel, dict]:
    payload = load_checkpoint(path, expect_model=STYLE_MODEL_NAME)
    model = StyleModel(config_from_dict(StyleEncoderConfig, payload["config"]["style_encoder"]))
    model.load_state_dict(payload["model"])
    return model.eval(), payload["meta"]


def system_from_style(cfg: GeneratorConfig, style: StyleModel | None) -> StyGazeTalkSystem:
    """A fresh system whose motion statistics and frozen style encoder come from a stage-1 model."""
    system = StyGazeTalkSystem(cfg, style.cfg if style is not None else None)
    if style is not None and system.style_encoder is not None:
        system.motion_norm.load_state_dict(style.motion_norm.state_dict())
        system.style_encoder.load_state_dict(style.encoder.state_dict())
    return system


def save_system(path: str | Path, system: StyGazeTalkSystem, meta: dict) -> Path:
    config = {"generator": system.cfg.to_dict(),
              "style_encoder": system.se_cfg.to_dict() if system.se_cfg is not None else None}
    return save_checkpoint(path, model_state=system.state_dict(), config=config, meta={"model": MODEL_NAME, **meta})


def load_system(path: str | Path) -> tuple[StyGazeTalkSystem, dict]:
    """The system of a stage-2 checkpoint, in eval mode, and the checkpoint's meta (+ ``digest``)."""
    path = Path(path)
    if not path.is_file():
        raise InputError(path, "StyGazeTalk checkpoint not found; train one with: " + REPRODUCE)
    payload = load_checkpoint(path, expect_model=MODEL_NAME)
    cfg = config_from_dict(GeneratorConfig, payload["config"]["generator"])
    se = payload["config"]["style_encoder"]
    system = StyGazeTalkSystem(cfg, config_from_dict(StyleEncoderConfig, se) if se is not None else None)
    system.load_state_dict(payload["model"])
    return system.eval(), {**payload["meta"], "digest": file_digest(path), "path": str(path)}
