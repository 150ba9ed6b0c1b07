"""Joining the process group that ``torchrun`` describes (data-parallel training of reference models).

Under ``torchrun`` the environment holds ``RANK``, ``WORLD_SIZE`` and ``LOCAL_RANK``; the process then
joins the group with NCCL when CUDA is requested and available, Gloo otherwise. Outside torchrun it is
one inactive process of rank 0.
"""

from __future__ import annotations

import os
from dataclasses import dataclass

import torch
import torch.distributed as dist


@dataclass(frozen=True)
class DistributedInfo:
    rank: int = 0
    world_size: int = 1
    local_rank: int = 0
    active: bool = False  # launched by torchrun and joined to its process group

    @property
    def is_main(self) -> bool:
        return self.rank == 0


def uses_cuda(device: str) -> bool:
    """True when ``device`` asks for CUDA and CUDA is available."""
    return device.startswith("cuda") and torch.cuda.is_available()


def init_distributed(device: str) -> DistributedInfo:
    """Join torchrun's process group when launched by torchrun; else a single inactive process."""
    if "RANK" not in os.environ or "WORLD_SIZE" not in os.environ:
        return DistributedInfo()
    local_rank = int(os.environ.get("LOCAL_RANK", "0"))
    cuda = uses_cuda(device)
    if cuda:
        torch.cuda.set_device(local_rank)
    if not dist.is_initialized():
        dist.init_process_group("nccl" if cuda else "gloo")
    return DistributedInfo(dist.get_rank(), dist.get_world_size(), local_rank, True)
