"""A trained SFMS: the frozen tokenizer and the predictor, saved and loaded as one checkpoint."""

from __future__ import annotations

from pathlib import Path

from torch import nn

from dyadbench.errors import InputError
from dyadbench.training.checkpoint import load_checkpoint
from models.sfms.config import PredictorConfig, TokenizerConfig, from_dict, to_dict
from models.sfms.predictor import SFMSPredictor
from models.sfms.tokenizer import SFMSTokenizer

TOKENIZER_MODEL = "sfms-tokenizer"
PREDICTOR_MODEL = "sfms"


class SFMS(nn.Module):
    """Tokenizer (stage 1) + predictor (stage 2); the checkpoint of ``dyadbench train sfms``."""

    def __init__(self, tokenizer: SFMSTokenizer, predictor: SFMSPredictor):
        super().__init__()
        if tokenizer.cfg.window != predictor.cfg.window:
            raise InputError(None, f"tokenizer window {tokenizer.cfg.window} != predictor past + future "
                                   f"{predictor.cfg.window}")
        self.tokenizer, self.predictor = tokenizer, predictor

    def config(self) -> dict:
        return {"tokenizer": to_dict(self.tokenizer.cfg), "predictor": to_dict(self.predictor.cfg)}


def tokenizer_from_checkpoint(payload: dict) -> SFMSTokenizer:
    cfg = from_dict(TokenizerConfig, payload["config"]["tokenizer"])
    model = SFMSTokenizer(cfg)
    state = {k.removeprefix("tokenizer."): v for k, v in payload["model"].items() if not k.startswith("predictor.")}
    model.load_state_dict(state)
    return model.eval()


def load_tokenizer(path: str | Path) -> SFMSTokenizer:
    """The tokenizer of a tokenizer checkpoint or of a full SFMS checkpoint, in eval mode."""
    payload = load_checkpoint(path)
    if payload["meta"].get("model") not in (TOKENIZER_MODEL, PREDICTOR_MODEL):
        raise InputError(path, f"not an SFMS checkpoint (model {payload['meta'].get('model')!r})")
    return tokenizer_from_checkpoint(payload)


def checkpoint_layout(meta: dict) -> str:
    """The motion layout a checkpoint was trained on (its ``meta["data"]["layout"]``; checkpoints written
    before training recorded it were all trained on flame56 motion)."""
    return (meta.get("data") or {}).get("layout", "flame56")


def load_sfms(path: str | Path) -> tuple[SFMS, dict]:
    """(model in eval mode, checkpoint meta) from a ``dyadbench train sfms`` checkpoint."""
    payload = load_checkpoint(path, expect_model=PREDICTOR_MODEL)
    tokenizer = tokenizer_from_checkpoint(payload)
    pcfg = from_dict(PredictorConfig, payload["config"]["predictor"])
    predictor = SFMSPredictor(pcfg, tokenizer.cfg.dim, tokenizer.cfg.n_classes, tokenizer.cfg.per_channel)
    model = SFMS(tokenizer, predictor)
    model.load_state_dict(payload["model"])
    return model.eval(), payload["meta"]
