"""TIMAR training: one process, or data-parallel under ``torchrun`` (torch.distributed, DDP).

Under ``torchrun`` (environment variables ``RANK``/``WORLD_SIZE``/``LOCAL_RANK`` set) the process group
is initialised (NCCL on GPUs, Gloo on CPUs), the model is wrapped in DistributedDataParallel and the
windows are split by a DistributedSampler; rank 0 writes checkpoints. Otherwise training runs in one
process with a seeded shuffle per epoch.

Recipe (per configuration, see :mod:`models.timar.config`): AdamW (0.9, 0.95) with weight decay on
weight matrices of the backbone only (none on biases, norms, learned tokens/positions, or the
diffusion head), linear warm-up over ``warmup_epochs`` then constant learning rate, gradient
clipping, EMA of the weights (decay ``min(ema_decay, (1 + step) / (10 + step))``) used at test.
Speech statistics, and with ``motion_norm = "per_dim"`` motion statistics, come from the training
windows' clips and are stored as model buffers (so in every checkpoint).
After every epoch ``<out>/checkpoint.pt`` holds the EMA weights, the config, the data digest and the
full training state (raw weights, optimiser, EMA, RNG), so ``--resume`` continues bit-exactly.
"""

from __future__ import annotations

import sys
import time
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
import torch
import torch.distributed as dist
from torch.nn.parallel import DistributedDataParallel
from torch.utils.data import DataLoader, DistributedSampler, RandomSampler
from tqdm import tqdm

from dyadbench.datasets.base import ClipSource
from dyadbench.errors import ConfigError, InputError
from dyadbench.seeding import derive_seed
from dyadbench.training.checkpoint import load_checkpoint, save_checkpoint
from dyadbench.training.distributed import DistributedInfo, init_distributed
from dyadbench.training.ema import EMA
from models.timar.config import TimarConfig
from models.timar.data import WindowDataset, data_digest
from models.timar.frontends import make_frontend
from models.timar.layouts import timar_layout
from models.timar.model import TimarModel

MODEL_NAMES = {"faithful": "timar", "stream": "timar-stream"}


@dataclass(frozen=True)
class TrainSettings:
    epochs: int = 1
    batch_size: int | None = None  # None: the config's batch size
    lr: float | None = None  # None: the config's learning rate
    warmup_epochs: float = 0.0
    seed: int = 0
    stride_turns: int = 8
    device: str = "cpu"
    wav2vec_weights: str | None = None
    command: str = ""




def parameter_groups(model: TimarModel, weight_decay: float) -> list[dict]:
    """Weight decay only on backbone weight matrices (not biases, norms, tokens, positions, the head)."""
    no_decay_names = {"special_tokens", "pos_embed", "head_pos_embed", "turn_keys"}
    decay, no_decay = [], []
    for name, p in model.named_parameters():
        if p.ndim < 2 or name in no_decay_names or name.startswith("head."):
            no_decay.append(p)
        else:
            decay.append(p)
    return [{"params": decay, "weight_decay": weight_decay}, {"params": no_decay, "weight_decay": 0.0}]


def _loader(dataset: WindowDataset, batch_size: int, seed: int, epoch: int, info: DistributedInfo) -> DataLoader:
    if info.active:
        sampler = DistributedSampler(dataset, num_replicas=info.world_size, rank=info.rank, shuffle=True, seed=seed)
        sampler.set_epoch(epoch)
    else:
        sampler = RandomSampler(dataset, generator=torch.Generator().manual_seed(derive_seed(seed, "epoch", epoch)))
    return DataLoader(dataset, batch_size=batch_size, sampler=sampler)


def _gather_rng_states(info: DistributedInfo) -> list[torch.Tensor]:
    """Every rank's torch RNG state (rank order), so a resumed run continues each rank's stream."""
    if not info.active or info.world_size == 1:
        return [torch.get_rng_state()]
    states: list = [None] * info.world_size
    dist.all_gather_object(states, torch.get_rng_state())
    return states


def train_timar_model(cfg: TimarConfig, source: ClipSource, out_dir: Path, settings: TrainSettings, *,
                      resume: Path | None = None, export: Path | None = None, progress: bool = True) -> Path:
    """Train on ``source``; returns the path of ``<out_dir>/checkpoint.pt`` (written by rank 0)."""
    if settings.epochs < 1:
        raise ConfigError(f"epochs must be >= 1, got {settings.epochs}")
    model_name = MODEL_NAMES[cfg.variant]
    info = init_distributed(settings.device)
    device = torch.device(f"cuda:{info.local_rank}" if settings.device.startswith("cuda") and info.active
                          else settings.device)
    batch_size = settings.batch_size or cfg.batch_size
    lr = settings.lr if settings.lr is not None else cfg.lr

    layout = timar_layout(cfg.motion_dim)
    frontend = make_frontend(cfg, fps=layout.fps, wav2vec_weights=settings.wav2vec_weights)
    dataset = WindowDataset(source, frontend, cfg, settings.stride_turns, progress=progress and info.is_main)
    digest = data_digest(source)
    torch.manual_seed(derive_seed(settings.seed, "init"))
    model = TimarModel(cfg)
    mean, std = dataset.speech_statistics()
    model.speech_mean.copy_(torch.from_numpy(mean))
    model.speech_std.copy_(torch.from_numpy(std))
    if cfg.motion_norm == "per_dim":
        mean, std = dataset.motion_statistics()
        model.motion_mean.copy_(torch.from_numpy(mean))
        model.motion_std.copy_(torch.from_numpy(std))
    model.to(device)
    ema = EMA(model, cfg.ema_decay)
    optimizer = torch.optim.AdamW(parameter_groups(model, cfg.weight_decay), lr=lr, betas=(0.9, 0.95))
    start_epoch, step, history = 0, 0, []
    torch.manual_seed(derive_seed(settings.seed, "train", info.rank))

    if resume is not None:
        state = load_checkpoint(resume, expect_model=model_name)
        if state["config"] != cfg.to_dict():
            raise InputError(resume, "checkpoint was trained with a different configuration")
        if state["meta"].get("data_digest") != digest:
            raise InputError(resume, "checkpoint was trained on different data (data digest differs)")
        if "train_state" not in state:
            raise InputError(resume, "checkpoint has no training state (weights-only export); cannot resume")
        ts = state["train_state"]
        model.load_state_dict(ts["model"])
        ema.load_state_dict(state["model"])
        optimizer.load_state_dict(ts["optimizer"])
        torch.set_rng_state(ts["rng"][info.rank] if info.rank < len(ts["rng"]) else ts["rng"][0])
        start_epoch, step, history = ts["epoch"], ts["step"], list(ts["history"])

    net = DistributedDataParallel(model) if info.active else model
    steps_per_epoch = len(_loader(dataset, batch_size, settings.seed, 0, info))
    warmup_steps = settings.warmup_epochs * steps_per_epoch
    out_dir = Path(out_dir)
    checkpoint = out_dir / "checkpoint.pt"
    meta = {"model": model_name, "config_name": cfg.name, "layout": layout.name, "data_digest": digest,
            "data": source.describe(),
            "windows": len(dataset), "seed": settings.seed, "command": settings.command,
            "settings": asdict(settings), "world_size": info.world_size}

    for epoch in range(start_epoch, settings.epochs):
        net.train()
        started, losses = time.time(), []
        bar = tqdm(_loader(dataset, batch_size, settings.seed, epoch, info), desc=f"epoch {epoch + 1}/{settings.epochs}",
                   disable=not (progress and info.is_main))
        for batch in bar:
            for group in optimizer.param_groups:
                group["lr"] = lr * min(1.0, (step + 1) / warmup_steps) if warmup_steps > 0 else lr
            loss = net(**{k: v.to(device) for k, v in batch.items()})
            optimizer.zero_grad(set_to_none=True)
            loss.backward()
            torch.nn.utils.clip_grad_norm_(model.parameters(), cfg.grad_clip)
            optimizer.step()
            ema.decay = min(cfg.ema_decay, (1 + step) / (10 + step))
            ema.update(model)
            step += 1
            losses.append(loss.item())
            bar.set_postfix(loss=f"{np.mean(losses[-20:]):.4f}")
        history.append({"epoch": epoch + 1, "loss": float(np.mean(losses)), "steps": step,
                        "seconds": round(time.time() - started, 1)})
        rng_states = _gather_rng_states(info)
        if info.is_main:
            train_state = {"model": model.state_dict(), "optimizer": optimizer.state_dict(), "rng": rng_states,
                           "epoch": epoch + 1, "step": step, "history": history}
            save_checkpoint(checkpoint, model_state=ema.state_dict(), config=cfg.to_dict(),
                            meta={**meta, "epoch": epoch + 1, "step": step, "history": history},
                            train_state=train_state)
            print(f"epoch {epoch + 1}: loss {history[-1]['loss']:.4f} ({history[-1]['seconds']} s), "
                  f"saved {checkpoint}", file=sys.stderr)
    if export is not None and info.is_main:
        state = load_checkpoint(checkpoint, expect_model=model_name)
        save_checkpoint(export, model_state=state["model"], config=state["config"], meta=state["meta"])
        print(f"exported EMA weights to {export}", file=sys.stderr)
    if info.active:
        dist.barrier()
    return checkpoint
