"""Data-parallel training under ``torchrun`` via torch.distributed (world size 1 without it)."""

from __future__ import annotations

from dataclasses import dataclass

import torch
import torch.distributed as dist
from torch import nn

from dyadbench.training.distributed import init_distributed, uses_cuda


@dataclass(frozen=True)
class World:
    rank: int
    size: int
    device: torch.device

    @property
    def main(self) -> bool:
        return self.rank == 0


def init_world(device: str = "cpu") -> World:
    """Join the process group that ``torchrun`` describes (see :mod:`dyadbench.training.distributed`)."""
    info = init_distributed(device)
    if not info.active:
        return World(0, 1, torch.device(device))
    local_device = torch.device(f"cuda:{info.local_rank}" if uses_cuda(device) else "cpu")
    return World(info.rank, info.world_size, local_device)


def wrap(model: nn.Module, world: World) -> nn.Module:
    """DDP-wrap for world size > 1 (unused parameters allowed: the scorer idles in warm-up)."""
    if world.size == 1:
        return model
    ids = [world.device.index] if world.device.type == "cuda" else None
    return nn.parallel.DistributedDataParallel(model, device_ids=ids, find_unused_parameters=True)


def close_world(world: World) -> None:
    if dist.is_initialized():
        dist.destroy_process_group()
