"""Model factories registered as ``timar`` and ``timar-stream`` in :data:`dyadbench.registry.MODELS`.

Both load a checkpoint written by ``dyadbench train timar`` / ``timar-stream`` (or by ``dyadbench weights
convert``): ``options.weights`` if given, else the tiny checkpoint shipped with the package
(``models/timar/checkpoints/``, :mod:`dyadbench.shipped`; a checkpoint whose motion layout is not the split's,
:mod:`models.timar.layouts`, is refused naming the file). ``timar`` also takes the released TIMAR checkpoint, converted in memory
(:mod:`models.timar.official`); the result then records the official file's digest and
``"format": "official"``. Every file is read with ``torch.load(weights_only=True)`` (only the globals
the release's format needs are allowed). Weights converted from the release sample as the release does
(learned variance unclamped) unless ``clamp_variance`` is given. Options:
``cfg_scale`` (classifier-free guidance, 1 = off as in the published runs), ``seed`` (per-stream
seeds come from the protocol), ``device``, and in ``extra``: ``cache`` (default True; False re-encodes
as the released implementation does), ``temperature`` (default 1), ``clamp_variance`` (default True;
False samples exactly as the released code, see :meth:`models.timar.diffusion.GaussianDiffusion.sample`),
``wav2vec_weights`` (local folder of the wav2vec 2.0 model for configurations that use it),
``guidance_null`` (what the unconditional branch nulls: ``current-turn``, the release and default, or
``every-turn``; see :mod:`models.timar.streaming`). With guidance on (``cfg_scale`` != 1) the recorded
model version names the null policy (``<version>+null-current-turn``), so results sampled with another
unconditional branch are told apart and found stale.
"""

from __future__ import annotations

from pathlib import Path

from dyadbench.errors import InputError
from dyadbench.protocol.interface import ModelInfo, ModelOptions
from dyadbench.shipped import shipped_checkpoint
from dyadbench.torch_files import load_tensors_only
from dyadbench.training.checkpoint import check_checkpoint, file_digest
from models.timar.config import TimarConfig
from models.timar.frontends import make_frontend
from models.timar.layouts import TIMAR_LAYOUTS, timar_layout
from models.timar.model import TimarModel, with_motion_statistics
from models.timar.official import convert_official, is_official, official_globals
from models.timar.streaming import BandStream, FaithfulStream

CHECKPOINT_DIR = Path(__file__).parent / "checkpoints"
SHIPPED_STEM = {"timar": "timar-tiny", "timar-stream": "timar-stream-tiny"}
TRAIN_HINT = {"timar": "dyadbench train timar --config tiny --export PATH",
              "timar-stream": "dyadbench train timar-stream --config tiny --export PATH"}


def shipped(name: str, dataset: str | None = None) -> Path:
    """The tiny checkpoint shipped for ``name``, trained on ``dataset``'s corpus (:mod:`dyadbench.shipped`)."""
    return shipped_checkpoint(CHECKPOINT_DIR, SHIPPED_STEM[name], dataset)


def load_timar(name: str, weights: Path | None, dataset: str | None = None) -> tuple[TimarModel, Path, dict]:
    """(model with the checkpoint's EMA weights, checkpoint path, checkpoint meta); without ``weights``, the
    checkpoint shipped for ``dataset``.

    A checkpoint from before motion normalisation (no ``motion_norm`` in its config, no motion
    statistics in its weights) loads with ``motion_norm = "none"`` and identity statistics. The released
    TIMAR checkpoint (``timar`` only) is converted in memory.
    """
    path = Path(weights) if weights is not None else shipped(name, dataset)
    if not path.is_file():
        where = "given with --weights" if weights is not None else "shipped with the package"
        raise InputError(path, f"no {name} checkpoint ({where}); train one with `{TRAIN_HINT[name]}` "
                               f"and pass it with --weights PATH")
    payload = load_tensors_only(path, allowed_globals=official_globals(), what=f"{name} checkpoint")
    if is_official(payload):
        if name != "timar":
            raise InputError(path, f"this is the released TIMAR checkpoint (the faithful model): use --model timar, "
                                   f"not {name}")
        model, meta = convert_official(path, payload)
        return model, path, meta
    payload = check_checkpoint(path, payload, expect_model=name)
    cfg = TimarConfig.from_dict(payload["config"])
    model = TimarModel(cfg)
    try:
        model.load_state_dict(with_motion_statistics(payload["model"], cfg.motion_dim))
    except RuntimeError as exc:
        raise InputError(path, f"weights do not fit the {cfg.name} configuration: {exc}") from None
    return model, path, payload["meta"]


def check_layout(name: str, model: TimarModel, path: Path, wanted: str | None) -> None:
    """Refuse a checkpoint whose motion layout is not the split's ``wanted`` layout, naming the file."""
    have = timar_layout(model.cfg.motion_dim)
    if wanted is None or wanted == have.name:
        return
    hint = (f"train one with `dyadbench train {name} --dataset {wanted} --data ROOT --export PATH`"
            if wanted in TIMAR_LAYOUTS else f"{name} runs on {', '.join(TIMAR_LAYOUTS)} only")
    raise InputError(path, f"this {name} checkpoint generates {have.name} motion ({have.motion_dim} dims at "
                           f"{have.fps:g} fps); the split is {wanted}: {hint}")


def _build(name: str, options: ModelOptions, stream_cls: type[FaithfulStream] | type[BandStream]):
    model, path, meta = load_timar(name, options.weights, options.dataset)
    check_layout(name, model, path, options.extra.get("layout"))
    use_cache = bool(options.extra.get("cache", True))
    temperature = float(options.extra.get("temperature", 1.0))
    clamp_variance = bool(options.extra.get("clamp_variance", meta.get("sampler", {}).get("clamp_variance", True)))
    guidance_null = str(options.extra.get("guidance_null", "current-turn"))
    version = str(meta.get("dyadbench_version", "1"))
    if options.cfg_scale != 1.0:
        version += f"+null-{guidance_null}"
    info = ModelInfo(name=name, version=version, weights_digest=file_digest(path),
                     weights_path=str(path), layout=timar_layout(model.cfg.motion_dim).name,
                     config={**model.cfg.to_dict(), "cfg_scale": options.cfg_scale, "cache": use_cache,
                             "temperature": temperature, "clamp_variance": clamp_variance,
                             "guidance_null": guidance_null, "format": meta.get("format", "native"),
                             "converted_from": meta.get("converted_from"),
                             "wav2vec_weights": options.extra.get("wav2vec_weights"),
                             "data_digest": meta.get("data_digest"),
                             "train_epochs": meta.get("epoch"), "train_command": meta.get("command")})
    frontend = make_frontend(model.cfg, wav2vec_weights=options.extra.get("wav2vec_weights"))
    return stream_cls(model, frontend, info, cfg_scale=options.cfg_scale, use_cache=use_cache,
                      temperature=temperature, clamp_variance=clamp_variance, guidance_null=guidance_null,
                      device=options.device)


def build_timar(options: ModelOptions) -> FaithfulStream:
    """The faithful TIMAR (window-indexed positions, exact cache while the window grows)."""
    return _build("timar", options, FaithfulStream)


def build_timar_stream(options: ModelOptions) -> BandStream:
    """The streaming-native TIMAR variant (per-turn sliding band, exact cache at every turn)."""
    return _build("timar-stream", options, BandStream)
