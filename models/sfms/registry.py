"""The SFMS model factories registered in :data:`dyadbench.registry.MODELS`: ``sfms`` (:func:`build_sfms`, the
shared keyframe mask of the presets, or any SFMS weights) and ``sfms-channel`` (:func:`build_sfms_channel`,
per-channel keyframe allocation, the paper's §V-B)."""

from __future__ import annotations

from pathlib import Path

from dyadbench.errors import InputError
from dyadbench.protocol.interface import ModelInfo, ModelOptions
from dyadbench.shipped import shipped_checkpoint
from dyadbench.training.checkpoint import file_digest
from models.sfms.bundle import checkpoint_layout, load_sfms
from models.sfms.stream import SFMSStreamingModel

CHECKPOINT_DIR = Path(__file__).parent / "checkpoints"
STEM, CHANNEL_STEM = "sfms-tiny", "sfms-tiny-channel"
REPRODUCE = ("dyadbench train sfms-tokenizer --config tiny{sharing} --export TOK.pt && dyadbench train sfms --config "
             "tiny --clips 400 --steps 4000 --tokenizer TOK.pt --export models/sfms/checkpoints/{stem}-v2.pt")


def shipped(dataset: str | None = None, stem: str = STEM) -> Path:
    """The tiny checkpoint ``stem`` shipped for ``dataset``'s corpus (:mod:`dyadbench.shipped`)."""
    return shipped_checkpoint(CHECKPOINT_DIR, stem, dataset)


def build_sfms(options: ModelOptions) -> SFMSStreamingModel:
    """The SFMS listener model from ``options.weights`` or the shipped tiny checkpoint (shared keyframe mask).

    ``options.extra["greedy"]`` (bool) overrides the configured sampling (D17).
    """
    return _build(options, "sfms", STEM, channel_only=False)


def build_sfms_channel(options: ModelOptions) -> SFMSStreamingModel:
    """SFMS with per-channel keyframe allocation (D1 ``mask_sharing="channel"``): ``options.weights`` or the
    shipped per-channel tiny checkpoint (corpus v2); weights with a shared mask are refused."""
    return _build(options, "sfms-channel", CHANNEL_STEM, channel_only=True)


def _build(options: ModelOptions, name: str, stem: str, *, channel_only: bool) -> SFMSStreamingModel:
    """Model ``name`` from ``options.weights`` or the shipped ``stem`` checkpoint; ``channel_only`` refuses
    weights with a shared keyframe mask."""
    path = Path(options.weights) if options.weights is not None else shipped(options.dataset, stem)
    if not path.is_file():
        where = "--weights" if options.weights is not None else "the shipped checkpoint"
        sharing = " --mask-sharing channel" if channel_only else ""
        raise InputError(path, f"{name} weights not found ({where}); train them with: "
                               f"{REPRODUCE.format(sharing=sharing, stem=stem)}")
    model, meta = load_sfms(path)
    if channel_only and not model.tokenizer.cfg.per_channel:
        raise InputError(path, f"{name} needs per-channel keyframe weights (mask_sharing channel); these share "
                               "one mask across channels: evaluate them with --model sfms")
    layout = checkpoint_layout(meta)
    wanted = options.extra.get("layout")
    if wanted is not None and wanted != layout:
        raise InputError(path, f"this SFMS checkpoint was trained on {layout} motion; the split is {wanted} "
                               "(train one on that layout, or pass its --weights)")
    info = ModelInfo(name=name, layout=layout, version="1", weights_digest=file_digest(path),
                     weights_path=str(path), config={**model.config(), "train_meta": meta})
    return SFMSStreamingModel(model, info, greedy=options.extra.get("greedy"))
