"""Model factories ``dualtalk`` (progressive-context streaming) and ``dualtalk-offline`` (whole clip).

Weights: ``options.weights`` if given, else the ``tiny`` checkpoint shipped with the package
(``models/dualtalk/checkpoints/dualtalk-tiny.pt``, written by ``dyadbench train dualtalk``). A given file is
either a dyadbench checkpoint or the released ``DualTalk.pth`` (a bare state dict, detected by its
content), which also needs ``extra["wav2vec_weights"]``: a local wav2vec 2.0 folder whose config
(only) describes the two encoders. Both files are read with ``torch.load(weights_only=True)``.
"""

from __future__ import annotations

from pathlib import Path

from dyadbench.errors import InputError
from dyadbench.protocol.interface import ModelInfo, ModelOptions
from dyadbench.shipped import shipped_checkpoint
from dyadbench.torch_files import load_tensors_only
from dyadbench.training.checkpoint import file_digest
from models.dualtalk.config import DualTalkConfig
from models.dualtalk.model import DualTalkModel
from models.dualtalk.official import is_official, model_from_state, wav2vec_config
from models.dualtalk.runtime import DualTalkOffline, DualTalkRunner, DualTalkStream

MODEL_NAME = "dualtalk"
CHECKPOINT_DIR = Path(__file__).parent / "checkpoints"
TRAIN_HINT = "dyadbench train dualtalk --export PATH"
NATIVE_KEYS = {"model", "config", "meta"}


def shipped(dataset: str | None = None) -> Path:
    """The tiny checkpoint shipped for ``dataset``'s corpus (:mod:`dyadbench.shipped`)."""
    return shipped_checkpoint(CHECKPOINT_DIR, "dualtalk-tiny", dataset)


def load_dualtalk(weights: Path | None, wav2vec_folder: str | None = None,
                  dataset: str | None = None) -> tuple[DualTalkModel, Path, dict]:
    """(model in eval mode, checkpoint path, meta); meta is ``{"format": "official"}`` for the released file.
    Without ``weights``: the checkpoint shipped for ``dataset``."""
    path = Path(weights) if weights is not None else shipped(dataset)
    if not path.is_file():
        where = "given with --weights" if weights is not None else "shipped with the package"
        raise InputError(path, f"no DualTalk checkpoint ({where}); train one with `{TRAIN_HINT}` "
                               f"and pass it with --weights PATH")
    payload = load_tensors_only(path, what="DualTalk checkpoint")
    if is_official(payload):
        return model_from_state(path, payload, wav2vec_config(wav2vec_folder)), path, {"format": "official"}
    if not (isinstance(payload, dict) and NATIVE_KEYS <= set(payload)
            and payload["meta"].get("model") == MODEL_NAME):
        found = payload["meta"].get("model") if isinstance(payload, dict) and isinstance(payload.get("meta"), dict) \
            else None
        raise InputError(path, "not a DualTalk checkpoint (neither the released bare state dict nor a dyadbench "
                               f"`train dualtalk` checkpoint{f'; it is for model {found!r}' if found else ''})")
    model = DualTalkModel(DualTalkConfig.from_dict(payload["config"]))
    try:
        model.load_state_dict(payload["model"])
    except RuntimeError as exc:
        raise InputError(path, f"weights do not fit the DualTalk {model.cfg.name} configuration: {exc}") from None
    return model.eval(), path, {"format": "dyadbench", **payload["meta"]}


def _info(name: str, model: DualTalkModel, path: Path, meta: dict, **extra) -> ModelInfo:
    return ModelInfo(name=name, version=str(meta.get("dyadbench_version", "1")), weights_digest=file_digest(path),
                     weights_path=str(path),
                     config={**model.cfg.to_dict(), **extra, "weights_format": meta["format"], "data_digest": meta.get("data_digest"),
                             "train_steps": meta.get("step"), "train_command": meta.get("command")})


def build_dualtalk(options: ModelOptions) -> DualTalkStream:
    """DualTalk under the progressive-context streaming protocol (window of min(t, n) + 1 turns)."""
    model, path, meta = load_dualtalk(options.weights, options.extra.get("wav2vec_weights"), options.dataset)
    info = _info(MODEL_NAME, model, path, meta, window="last min(t, n) + 1 turns, current turn kept")
    return DualTalkStream(DualTalkRunner(model, options.device), info)


def build_dualtalk_offline(options: ModelOptions) -> DualTalkOffline:
    """DualTalk over the whole clip at once (the published DualTalk protocol; whole-clip normalisation)."""
    model, path, meta = load_dualtalk(options.weights, options.extra.get("wav2vec_weights"), options.dataset)
    info = _info(f"{MODEL_NAME}-offline", model, path, meta, speech_norm="clip")
    return DualTalkOffline(DualTalkRunner(model, options.device), info)
