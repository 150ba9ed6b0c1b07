"""Checkpoints shared by every trained reference model: weights + config + provenance in one file.

A checkpoint is a ``torch.save`` dict with keys ``model`` (state dict, EMA weights when trained with
EMA), ``config`` (the model's full config as a plain dict), ``meta`` (model name, data digest, epoch,
seed, dyadbench version) and optionally ``train_state`` (raw weights, optimiser, scheduler, EMA, RNG
states) for resuming. Writes are atomic. :func:`file_digest` is the ``weights_digest`` in results.
"""

from __future__ import annotations

import hashlib
from pathlib import Path
from typing import Any

import torch

from dyadbench import __version__, atomic
from dyadbench.errors import InputError


def file_digest(path: str | Path) -> str:
    """sha256 hex digest of a file."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def run_record(device: str, threads: int) -> dict:
    """What a checkpoint's ``meta`` records of how it was trained: the command line (``dyadbench …`` as typed;
    None when the trainer was called from Python, not through ``dyadbench``) and, under ``settings``, the
    torch device and the CPU threads."""
    from dyadbench.cli.invocation import recorded_command  # noqa: PLC0415  (click only when a trainer records)

    return {"command": recorded_command(), "settings": {"device": device, "threads": threads}}


def save_checkpoint(path: str | Path, *, model_state: dict, config: dict, meta: dict,
                    train_state: dict | None = None) -> Path:
    payload: dict[str, Any] = {"model": model_state, "config": config,
                               "meta": {**meta, "dyadbench_version": __version__}}
    if train_state is not None:
        payload["train_state"] = train_state
    return atomic.write_with(path, lambda tmp: torch.save(payload, tmp))


def load_checkpoint(path: str | Path, *, expect_model: str | None = None) -> dict:
    """Load a checkpoint on the CPU; clear errors for a missing file, a foreign file or a wrong model."""
    path = Path(path)
    if not path.is_file():
        raise InputError(path, "checkpoint file not found")
    try:
        payload = torch.load(path, map_location="cpu", weights_only=False)
    except Exception as exc:  # corrupted or not a torch file
        raise InputError(path, f"not a readable dyadbench checkpoint ({type(exc).__name__}: {exc})") from None
    return check_checkpoint(path, payload, expect_model)


def check_checkpoint(path: str | Path, payload: object, expect_model: str | None = None) -> dict:
    """``payload`` if it is a dyadbench checkpoint (of ``expect_model`` when given), else an InputError."""
    if not isinstance(payload, dict) or not {"model", "config", "meta"} <= set(payload):
        raise InputError(path, "not a dyadbench checkpoint (needs keys model, config, meta)")
    if expect_model is not None and payload["meta"].get("model") != expect_model:
        raise InputError(path, f"checkpoint is for model {payload['meta'].get('model')!r}, "
                               f"expected {expect_model!r}")
    return payload
