"""``build_sfms``: the model factory registered as ``sfms`` in :data:`dyadbench.registry.MODELS`."""

from __future__ import annotations

from pathlib import Path

from dyadbench.errors import InputError
from dyadbench.protocol.interface import ModelInfo, ModelOptions
from dyadbench.shipped import shipped_checkpoint
from dyadbench.training.checkpoint import file_digest
from models.sfms.bundle import checkpoint_layout, load_sfms
from models.sfms.stream import SFMSStreamingModel

CHECKPOINT_DIR = Path(__file__).parent / "checkpoints"
REPRODUCE = ("dyadbench train sfms-tokenizer --config tiny --export TOK.pt && dyadbench train sfms --config tiny "
             "--clips 400 --steps 4000 --tokenizer TOK.pt --export models/sfms/checkpoints/sfms-tiny.pt")


def shipped(dataset: str | None = None) -> Path:
    """The tiny checkpoint shipped for ``dataset``'s corpus (:mod:`dyadbench.shipped`)."""
    return shipped_checkpoint(CHECKPOINT_DIR, "sfms-tiny", dataset)


def build_sfms(options: ModelOptions) -> SFMSStreamingModel:
    """The SFMS listener model from ``options.weights`` or the shipped tiny checkpoint.

    ``options.extra["greedy"]`` (bool) overrides the configured sampling (D17).
    """
    path = Path(options.weights) if options.weights is not None else shipped(options.dataset)
    if not path.is_file():
        where = "--weights" if options.weights is not None else "the shipped checkpoint"
        raise InputError(path, f"SFMS weights not found ({where}); train them with: {REPRODUCE}")
    model, meta = load_sfms(path)
    layout = checkpoint_layout(meta)
    wanted = options.extra.get("layout")
    if wanted is not None and wanted != layout:
        raise InputError(path, f"this SFMS checkpoint was trained on {layout} motion; the split is {wanted} "
                               "(train one on that layout, or pass its --weights)")
    info = ModelInfo(name="sfms", layout=layout, version="1", weights_digest=file_digest(path),
                     weights_path=str(path), config={**model.config(), "train_meta": meta})
    return SFMSStreamingModel(model, info, greedy=options.extra.get("greedy"))
