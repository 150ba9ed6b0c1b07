"""Training the log-mel DualTalk (one process, seeded).

Loss as released: MSE(exp) + MSE(jaw) + MSE(neck) + MSE(velocity), velocity = frame-to-frame difference
of all 56 coefficients, on raw (unnormalised) motion. Adam, no weight decay, no EMA; lr 1e-4 as released
by default. The shipped ``tiny`` uses 5e-4: with a CPU budget of a few thousand steps (not 1000 epochs),
300 steps on 200 train clips reached a mean exp MSE of 0.339 at 5e-4 against 0.354 at 1e-4 (jaw 0.0025
vs 0.0099, velocity 0.038 vs 0.055). Each step draws one batch of random windows (:class:`models.dualtalk.data.WindowSampler`).
The log-mel standardisation statistics are measured on sampled training windows before the first step
and stored as model buffers. ``<out>/checkpoint.pt`` (weights, config, meta with the command, data digest
and loss history) is rewritten every ``save_every`` steps and at the end; at the end ``export`` too.
"""

from __future__ import annotations

import sys
import time
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
import torch
from tqdm import tqdm

from dyadbench.datasets.base import ClipSource
from dyadbench.errors import ConfigError
from dyadbench.seeding import derive_seed, rng
from dyadbench.training.checkpoint import save_checkpoint
from models.dualtalk.config import DualTalkConfig
from models.dualtalk.data import WindowSampler
from models.dualtalk.model import DualTalkModel
from models.timar.data import data_digest

GROUPS = {"exp": slice(0, 50), "jaw": slice(50, 53), "neck": slice(53, 56)}


@dataclass(frozen=True)
class TrainSettings:
    steps: int = 1000
    batch_size: int = 16
    lr: float = 1e-4
    min_seconds: int = 1
    max_seconds: int = 8
    seed: int = 0
    save_every: int = 500
    device: str = "cpu"
    command: str = ""


def dualtalk_loss(pred: torch.Tensor, target: torch.Tensor) -> tuple[torch.Tensor, dict[str, float]]:
    """MSE on exp + MSE on jaw + MSE on neck + MSE of the frame-to-frame velocity (released loss)."""
    parts = {name: torch.mean((pred[..., s] - target[..., s]) ** 2) for name, s in GROUPS.items()}
    parts["velocity"] = torch.mean((pred.diff(dim=1) - target.diff(dim=1)) ** 2)
    return sum(parts.values()), {k: v.item() for k, v in parts.items()}


def train_dualtalk_model(cfg: DualTalkConfig, source: ClipSource, out_dir: Path, settings: TrainSettings, *,
                         export: Path | None = None, progress: bool = True) -> Path:
    """Train on ``source``; returns ``<out_dir>/checkpoint.pt``."""
    if cfg.speech_frontend != "logmel":
        raise ConfigError("dyadbench trains the log-mel DualTalk only (the released size fine-tunes two wav2vec "
                          "2.0 models; load its official checkpoint with --weights instead)")
    if settings.steps < 1:
        raise ConfigError(f"steps must be >= 1, got {settings.steps}")
    sampler = WindowSampler(source, settings.min_seconds, settings.max_seconds, progress=progress)
    digest = data_digest(source)
    torch.manual_seed(derive_seed(settings.seed, "init"))
    model = DualTalkModel(cfg)
    mean, std = sampler.speech_statistics(rng(settings.seed, "speech statistics"))
    model.joint_encoder.speech_mean.copy_(torch.from_numpy(mean))
    model.joint_encoder.speech_std.copy_(torch.from_numpy(std))
    model.to(settings.device).train()
    optimizer = torch.optim.Adam(model.parameters(), lr=settings.lr)
    gen = rng(settings.seed, "windows")
    torch.manual_seed(derive_seed(settings.seed, "dropout"))
    checkpoint = Path(out_dir) / "checkpoint.pt"
    meta = {"model": "dualtalk", "config_name": cfg.name, "data_digest": digest, "data": source.describe(),
            "directions": len(sampler.directions), "seed": settings.seed, "command": settings.command,
            "settings": asdict(settings)}
    history, recent, started = [], [], time.time()
    bar = tqdm(range(1, settings.steps + 1), desc="dualtalk", disable=not progress)
    for step in bar:
        batch = {k: v.to(settings.device) for k, v in sampler.batch(gen, settings.batch_size).items()}
        pred = model(batch["speech1"], batch["speech2"], batch["user_motion"], batch["agent_motion"].shape[1])
        loss, parts = dualtalk_loss(pred, batch["agent_motion"])
        optimizer.zero_grad(set_to_none=True)
        loss.backward()
        optimizer.step()
        recent.append(parts)
        bar.set_postfix(loss=f"{loss.item():.4f}")
        if step % settings.save_every == 0 or step == settings.steps:
            history.append({"step": step, "seconds": round(time.time() - started, 1),
                            **{k: float(np.mean([r[k] for r in recent])) for k in recent[0]}})
            recent = []
            for path in (checkpoint, export) if step == settings.steps else (checkpoint,):
                if path is not None:
                    save_checkpoint(path, model_state=model.state_dict(), config=cfg.to_dict(),
                                    meta={**meta, "step": step, "history": history})
            print(f"step {step}: {history[-1]}", file=sys.stderr)
    return checkpoint
