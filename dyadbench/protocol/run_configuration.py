"""The configuration a run was requested with: what a stored result must match to stand in for a new run.

:func:`requested_configuration` is a canonical, JSON-able dict of everything a run's numbers depend on:
the model (name, version, weights digest: of ``--weights``, the shipped checkpoint or a baseline's
fitted statistics), the data (dataset, split, resolved root, content digest of the evaluated clips,
``--clips``), the protocol settings, guidance scale and seed, and the train split the model opened
(dataset, split, root, content digest; None when it opened none). Every result records it
(``EvalResult.configuration``); ``dyadbench sweep`` re-uses a stored result only when it equals the
requested one, and :func:`differences` says in words what differs.
"""

from __future__ import annotations

from dyadbench.datasets.base import ClipSource
from dyadbench.protocol.config import ProtocolConfig
from dyadbench.protocol.interface import ModelInfo
from dyadbench.protocol.perturbations import describe
from dyadbench.provenance import root_identity

#: What each key is called on the command line (or in words), for :func:`differences`.
LABELS = {"model": "the model", "model_version": "the model's version", "weights_digest": "the weights digest",
          "dataset": "--dataset", "split": "the split", "root": "--data", "data_digest": "the data's content",
          "clips": "--clips", "turn_seconds": "--turn-seconds", "context": "the context n", "tail": "--tail",
          "history_agent": "--history-agent", "cfg_scale": "--cfg-scale", "seed": "--seed",
          "speech_norm": "--speech-norm", "perturbations": "--perturb", "noise_scale": "--noise-scale",
          "train": "the train split"}
TRAIN_KEYS = ("dataset", "split", "root", "digest")


def requested_configuration(model_name: str, info: ModelInfo, source: ClipSource, clips: int | None,
                            config: ProtocolConfig, cfg_scale: float, data_digest: str,
                            train: dict | None) -> dict:
    """The canonical configuration of a run (see the module docstring); ``train``: the train split's record
    (:func:`dyadbench.protocol.train_split.train_record`). ``speech_norm`` is present only when not the default
    ``window``, and ``perturbations`` / ``noise_scale`` only for perturbed runs, so results recorded before the
    settings existed still match."""
    speech_norm = {} if config.speech_norm == "window" else {"speech_norm": config.speech_norm}
    perturbed = ({"perturbations": describe(config.perturbations), "noise_scale": config.noise_scale}
                 if config.perturbations else {})
    return {"model": model_name, "model_version": info.version, "weights_digest": info.weights_digest,
            "dataset": source.dataset, "split": source.split, "root": root_identity(source), "clips": clips,
            "data_digest": data_digest, "turn_seconds": config.turn_seconds,
            "context": config.context, "tail": config.tail, "history_agent": config.history_agent,
            "cfg_scale": float(cfg_scale), "seed": config.seed,
            "train": None if train is None else {k: train[k] for k in TRAIN_KEYS}, **speech_norm, **perturbed}


def differences(recorded: dict, requested: dict) -> list[str]:
    """What differs between a recorded and a requested configuration, e.g. ``--clips differs (was 2, now 3)``."""
    return [f"{LABELS.get(key, key)} differs (was {_show(key, recorded.get(key))}, "
            f"now {_show(key, requested.get(key))})"
            for key in dict.fromkeys([*requested, *recorded]) if recorded.get(key) != requested.get(key)]


def _show(key: str, value: object) -> str:
    """A short rendering: digests cut to 12 characters, the train split as its root and digest."""
    if value is None:
        return "all" if key == "clips" else "none"
    if isinstance(value, dict):
        return " ".join(f"{k}={_show(k, v)}" for k, v in value.items() if k in ("root", "digest"))
    if isinstance(value, str) and len(value) == 64 and all(c in "0123456789abcdef" for c in value):
        return value[:12]
    return str(value)
