"""The released TIMAR checkpoint (CoderChen01/towards-seamless-interaction) as a dyadbench TIMAR model.

The release saves ``{"model", "model_ema", "optimizer", "epoch", "scaler", "args"}`` with ``torch.save``;
``args`` is the training ``argparse.Namespace`` (holding numpy motion statistics). It is read only through
:func:`dyadbench.torch_files.load_tensors_only` with exactly the globals that format needs, and the
``model_ema`` weights are taken (the release's evaluation loads them before sampling).

Configuration: sizes from the tensor shapes and ``args`` (``token_embed_dim``,
``speech_snippet_embed_dim`` = the wav2vec width, ``max_context_time`` turns of
``motion_fps · chunk_second`` frames, ``diffloss_d``/``diffloss_w``); the number of attention heads is
stored nowhere, so it follows the named factory ``args.model`` (:data:`FACTORY_HEADS`) or an explicit
``heads``. Sampling settings are never read from ``args`` (they are the training flags): the released
evaluation samples with 5 respaced steps, temperature 1, guidance off and the learned variance
unclamped, which :data:`SAMPLER` records for the model factory.

Tensor correspondence (release → :class:`~models.timar.model.TimarModel`)::

    motion_encoder.{0,2}            → motion_embed.{0,2}
    speech_projection               → speech_proj
    z_proj / z_proj_ln              → token_proj / input_norm
    sep_tok_emb.weight (10, d_t)    → special_tokens = z_proj(sep_tok_emb)   (folded: the release
    fake_latent (1, d_t)            → null_token     = z_proj(fake_latent)    projects them with z_proj)
    mask_token (1, 1, D)            → mask_token (D)
    encoder_pos_embed_learned (1, 880, D), diffusion_pos_embed_learned → pos_embed, head_pos_embed
    encoder_blocks.i.{norm1,attn.qkv,attn.proj,norm2}, mlp.fc1/fc2 → blocks.i.…, mlp.0/mlp.3
    encoder_norm                    → norm
    diffloss.net.{time_embed.mlp.{0,2}, cond_embed, input_proj}     → head.…
    diffloss.net.res_blocks.i.{in_ln, mlp.{0,2}, adaLN_modulation.1} → head.blocks.i.{norm, mlp, modulation.1}
    diffloss.net.final_layer.{linear, adaLN_modulation.1}            → head.{final, final_modulation.1}

The release does not normalise motion (``do_norm`` off) or speech features, so the converted model keeps
identity motion and speech statistics (raw motion, ``motion_norm = "none"``). Every official key must be
mapped and every model tensor filled: anything else is an :class:`InputError` listing the keys.
"""

from __future__ import annotations

import re
from pathlib import Path

import torch
import torch.nn.functional as F

from dyadbench import __version__
from dyadbench.errors import ConfigError, InputError
from dyadbench.torch_files import NAMESPACE_WITH_ARRAYS, load_tensors_only, numpy_array_globals
from dyadbench.training.checkpoint import file_digest
from models.timar.config import TimarConfig
from models.timar.model import TimarModel

OFFICIAL_KEYS = frozenset({"model", "model_ema", "optimizer", "epoch", "scaler", "args"})
#: Attention heads of the release's named factories (the checkpoint does not store them).
FACTORY_HEADS = {"timar_base": 12, "timar_large": 16, "timar_huge": 16}
#: How the released evaluation samples (TUTORIAL's command), whatever the training flags in ``args`` say.
SAMPLER = {"sampling_steps": 5, "temperature": 1.0, "cfg_scale": 1.0, "clamp_variance": False}
#: Training flags of ``args`` that must hold for the converted model to compute what the release computes.
REQUIRED_FLAGS = {"use_encoder_only": True, "use_causal_attn": True, "do_norm": False, "epsilon_pred": False,
                  "noise_schedule": "cosine"}
WHAT = "official TIMAR checkpoint"

#: (official prefix, native prefix) of the tensors copied as they are; "{i}" stands for a block index.
_RENAMES = [("motion_encoder.0.", "motion_embed.0."), ("motion_encoder.2.", "motion_embed.2."),
            ("speech_projection.", "speech_proj."), ("z_proj.", "token_proj."), ("z_proj_ln.", "input_norm."),
            *[(f"encoder_blocks.{{i}}.{part}.", f"blocks.{{i}}.{part}.")
              for part in ("norm1", "norm2", "attn.qkv", "attn.proj")],
            ("encoder_blocks.{i}.mlp.fc1.", "blocks.{i}.mlp.0."), ("encoder_blocks.{i}.mlp.fc2.", "blocks.{i}.mlp.3."),
            ("encoder_norm.", "norm."),
            *[(f"diffloss.net.{part}.", f"head.{part}.")
              for part in ("time_embed.mlp.0", "time_embed.mlp.2", "cond_embed", "input_proj")],
            ("diffloss.net.res_blocks.{i}.in_ln.", "head.blocks.{i}.norm."),
            ("diffloss.net.res_blocks.{i}.mlp.0.", "head.blocks.{i}.mlp.0."),
            ("diffloss.net.res_blocks.{i}.mlp.2.", "head.blocks.{i}.mlp.2."),
            ("diffloss.net.res_blocks.{i}.adaLN_modulation.1.", "head.blocks.{i}.modulation.1."),
            ("diffloss.net.final_layer.linear.", "head.final."),
            ("diffloss.net.final_layer.adaLN_modulation.1.", "head.final_modulation.1.")]
_RESHAPED = {"mask_token": "mask_token", "encoder_pos_embed_learned": "pos_embed",
             "diffusion_pos_embed_learned": "head_pos_embed"}  # leading singleton dimensions dropped
_FOLDED = {"sep_tok_emb.weight": "special_tokens", "fake_latent": "null_token"}  # through z_proj


def official_globals() -> list:
    """The globals ``torch.load(weights_only=True)`` needs for the release's checkpoint."""
    return [*NAMESPACE_WITH_ARRAYS, *numpy_array_globals()]


def is_official(payload: object) -> bool:
    """Whether a loaded checkpoint has the release's top-level layout."""
    return isinstance(payload, dict) and OFFICIAL_KEYS <= set(payload)


def read_official(path: str | Path) -> dict:
    """The release's checkpoint dict, loaded safely; an InputError naming ``path`` for any other file."""
    payload = load_tensors_only(path, allowed_globals=official_globals(), what=WHAT)
    if not is_official(payload):
        keys = f"{len(payload)} keys: {', '.join(sorted(map(str, payload))[:3])}, ..." if isinstance(payload, dict) \
            else type(payload).__name__
        raise InputError(path, f"not an {WHAT} (expected a dict with keys {', '.join(sorted(OFFICIAL_KEYS))}; "
                               f"found {keys})")
    return payload


def official_config(path: str | Path, args: object, state: dict, heads: int | None = None) -> TimarConfig:
    """The :class:`TimarConfig` of a release checkpoint: ``args`` (training flags) and the tensor shapes."""
    flags = vars(args) if hasattr(args, "__dict__") else {}
    wrong = {k: flags.get(k) for k, v in REQUIRED_FLAGS.items() if flags.get(k) != v}
    if wrong:
        raise InputError(path, f"this {WHAT} was trained with {wrong}; dyadbench reproduces the release's "
                               f"encoder-only, turn-causal, x0-prediction, cosine, unnormalised model "
                               f"({REQUIRED_FLAGS})")
    factory = str(flags.get("model"))
    heads = heads or FACTORY_HEADS.get(factory)
    if heads is None:
        raise ConfigError(f"{path}: the number of attention heads is not stored in the checkpoint and its model "
                          f"factory {factory!r} is not one of the release's ({', '.join(FACTORY_HEADS)}); "
                          f"pass it with --heads N")
    d_t, speech_width = _shape(path, state, "speech_projection.weight")
    dim = _shape(path, state, "mask_token")[-1]
    frames = int(flags["motion_fps"] * flags["chunk_second"])
    depth = len({m.group(1) for k in state if (m := re.match(r"encoder_blocks\.(\d+)\.", k))})
    hidden = _shape(path, state, "encoder_blocks.0.mlp.fc1.weight")[0]
    return TimarConfig(
        name=factory, token_dim=d_t, speech_frontend="wav2vec", speech_width=speech_width,
        motion_dim=int(flags["motion_embed_dim"]), frames_per_turn=frames,
        samples_per_turn=int(flags["speech_frequency"] * flags["chunk_second"]),
        max_turns=int(flags["max_context_time"]), motion_norm="none", dim=dim, heads=heads, depth=depth,
        mlp_ratio=hidden / dim, dropout=float(flags["proj_dropout"]), attn_dropout=float(flags["attn_dropout"]),
        head_width=int(flags["diffloss_w"]), head_blocks=int(flags["diffloss_d"]),
        sampling_steps=SAMPLER["sampling_steps"], diffusion_batch_mul=int(flags["diffusion_batch_mul"]),
        cfg_dropout=float(flags["cond_drop_prob"]), lr=float(flags["lr"]), weight_decay=float(flags["weight_decay"]),
        grad_clip=float(flags["grad_clip"]), ema_decay=float(flags["ema_rate"]), batch_size=int(flags["batch_size"]))


def _shape(path: str | Path, state: dict, key: str) -> tuple[int, ...]:
    if key not in state:
        raise InputError(path, f"{WHAT} lacks tensor {key} (needed to read the model's sizes)")
    return tuple(state[key].shape)


def native_state(path: str | Path, state: dict, model: TimarModel, dtype: torch.dtype = torch.float32) -> dict:
    """The release's state dict mapped onto ``model``'s names (see the module docstring), in ``dtype``.

    Folded tokens are computed in float64 from the stored weights, then cast. Unmapped official keys and
    model tensors left unfilled are an InputError listing them.
    """
    expected = model.state_dict()
    native, unexpected = {}, []
    z_w, z_b = state.get("z_proj.weight"), state.get("z_proj.bias")
    for key, value in state.items():
        if key in _RESHAPED:
            target = expected[_RESHAPED[key]]
            native[_RESHAPED[key]] = value.reshape(target.shape) if value.numel() == target.numel() else value
        elif key in _FOLDED:
            if z_w is None or z_b is None:
                continue  # reported below as missing z_proj
            folded = F.linear(value.double(), z_w.double(), z_b.double())
            native[_FOLDED[key]] = folded if key == "sep_tok_emb.weight" else folded.reshape(-1)
        else:
            renamed = _translate(key, 0)
            if renamed is None:
                unexpected.append(key)
            else:
                native[renamed] = value
    identity = {"speech_mean": 0.0, "speech_std": 1.0, "motion_mean": 0.0, "motion_std": 1.0}
    native.update({k: torch.full_like(expected[k], v) for k, v in identity.items()})
    unexpected += [_official_name(k) for k in native if k not in expected]
    missing = [_official_name(k) for k in expected if k not in native]
    if missing or unexpected:
        parts = ([f"missing keys: {', '.join(sorted(set(missing)))}"] if missing else []) + \
                ([f"unexpected keys: {', '.join(sorted(set(unexpected)))}"] if unexpected else [])
        raise InputError(path, f"{WHAT} does not match the {model.cfg.name} configuration; " + "; ".join(parts))
    wrong = [f"{_official_name(k)} {tuple(v.shape)} (expected {tuple(expected[k].shape)})"
             for k, v in native.items() if v.shape != expected[k].shape]
    if wrong:
        raise InputError(path, f"{WHAT} has tensors of the wrong shape: {', '.join(wrong)}")
    return {k: v.to(dtype) for k, v in native.items()}


def _translate(key: str, side: int) -> str | None:
    """``key`` renamed from the official (``side`` 0) or native (1) name to the other; None if no rule fits."""
    for pair in _RENAMES:
        m = re.fullmatch(re.escape(pair[side]).replace(r"\{i\}", r"(?P<i>\d+)") + r"(weight|bias)", key)
        if m:
            return pair[1 - side].format(i=m.groupdict().get("i")) + m.group(m.lastindex)
    return None


def _official_name(native: str) -> str:
    """The release's name of a native key (for error messages)."""
    inverse = {v: k for k, v in {**_RESHAPED, **_FOLDED}.items()}
    return inverse.get(native) or _translate(native, 1) or native


def load_official(path: str | Path, *, heads: int | None = None, weights: str = "model_ema",
                  dtype: torch.dtype = torch.float32) -> tuple[TimarModel, dict]:
    """(converted model in eval mode, native meta) of a release checkpoint file (:func:`convert_official`)."""
    return convert_official(path, read_official(path), heads=heads, weights=weights, dtype=dtype)


def convert_official(path: str | Path, payload: dict, *, heads: int | None = None, weights: str = "model_ema",
                     dtype: torch.dtype = torch.float32) -> tuple[TimarModel, dict]:
    """(converted model in eval mode, native meta) of the release checkpoint ``payload`` read from ``path``;
    ``weights`` picks the state dict (``model_ema``, what the release evaluates with; ``model`` only for
    diagnostics)."""
    state = payload[weights]
    if not isinstance(state, dict) or not all(isinstance(v, torch.Tensor) for v in state.values()):
        raise InputError(path, f"{WHAT}: {weights!r} is not a state dict of tensors")
    cfg = official_config(path, payload["args"], state, heads)
    model = TimarModel(cfg).to(dtype)
    model.load_state_dict(native_state(path, state, model, dtype))
    meta = {"model": "timar", "format": "official", "dyadbench_version": __version__,
            "converted_from": {"file": Path(path).name, "digest": file_digest(path), "weights": weights,
                               "epoch": payload.get("epoch"), "factory": cfg.name, "heads": cfg.heads},
            "sampler": dict(SAMPLER)}
    return model.eval(), meta
