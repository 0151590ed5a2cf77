"""Data-parallel training under torchrun: which process this is, its device, the process group and the collectives.

    torchrun --standalone --nproc_per_node 2 -m tax3d.cli train --preset cpu ...

torchrun gives each process WORLD_SIZE, RANK, LOCAL_RANK, MASTER_ADDR and MASTER_PORT in its environment. Without
them (or with WORLD_SIZE=1) training runs in one process, as it always has. See docs/scaling.md.
"""

from __future__ import annotations

import datetime
import os
from dataclasses import dataclass

import torch
import torch.distributed as dist

from tax3d.errors import UsageError

LAUNCH = "torchrun --nproc_per_node N -m tax3d.cli train ..."
# Rank 0 validates and writes checkpoints while the other ranks wait at a barrier; torch's default timeout (10
# minutes for NCCL, torch.distributed.init_process_group docs) can be shorter than a validation of the paper's run.
TIMEOUT = datetime.timedelta(hours=2)


@dataclass(frozen=True)
class World:
    """This process's place among the training processes: rank, number of processes, rank on this machine."""

    rank: int = 0
    size: int = 1
    local_rank: int = 0

    @property
    def main(self) -> bool:
        return self.rank == 0

    @property
    def distributed(self) -> bool:
        return self.size > 1

    def share(self, batch_size: int) -> slice:
        """This rank's rows of a global batch: the size // world-size rows from rank * that on."""
        n = batch_size // self.size
        return slice(self.rank * n, (self.rank + 1) * n)


def _env_int(environ, name: str) -> int:
    value = environ.get(name)
    if value is None:
        raise UsageError(f"{name} is not set but WORLD_SIZE={environ['WORLD_SIZE']} is; expected a launch by "
                         f"torchrun ({LAUNCH})")
    try:
        return int(value)
    except ValueError:
        raise UsageError(f"{name}={value!r}: expected an integer (torchrun sets it)") from None


def from_env(environ=None) -> World:
    """The World torchrun's environment describes; one process when WORLD_SIZE is absent or 1."""
    environ = os.environ if environ is None else environ
    if environ.get("WORLD_SIZE", "1") == "1":
        return World()
    size = _env_int(environ, "WORLD_SIZE")
    rank, local_rank = _env_int(environ, "RANK"), _env_int(environ, "LOCAL_RANK")
    for name in ("MASTER_ADDR", "MASTER_PORT"):
        if name not in environ:
            raise UsageError(f"{name} is not set but WORLD_SIZE={size} is; expected a launch by torchrun ({LAUNCH})")
    if size < 1 or not 0 <= rank < size:
        raise UsageError(f"RANK={rank}, WORLD_SIZE={size}: expected 0 <= RANK < WORLD_SIZE (torchrun sets them)")
    return World(rank, size, local_rank)


def check_batch_size(world: World, batch_size: int) -> None:
    if batch_size % world.size:
        raise UsageError(f"--train.batch_size {batch_size}: not divisible by the {world.size} torchrun processes; "
                         f"expected a multiple of {world.size} (the global batch is split evenly between them)")


def rank_device(world: World, name: str, device: torch.device) -> torch.device:
    """The device of this rank: device itself in one process; cuda:LOCAL_RANK for a CUDA run under torchrun."""
    if not world.distributed or device.type != "cuda":
        return device
    if device.index is not None:
        raise UsageError(f"--train.device {name}: under torchrun each process uses cuda:LOCAL_RANK; expected cuda "
                         f"or auto (choose GPUs with CUDA_VISIBLE_DEVICES)")
    if world.local_rank >= torch.cuda.device_count():
        raise UsageError(f"--train.device {name}: process LOCAL_RANK={world.local_rank} needs cuda:"
                         f"{world.local_rank} but {torch.cuda.device_count()} CUDA devices are visible; expected "
                         f"--nproc_per_node at most {torch.cuda.device_count()}")
    return torch.device("cuda", world.local_rank)


def backend(device: torch.device) -> str:
    """NCCL between GPUs, gloo between CPU processes."""
    name = "nccl" if device.type == "cuda" else "gloo"
    available = dist.is_available() and (dist.is_nccl_available() if name == "nccl" else dist.is_gloo_available())
    if not available:
        raise UsageError(f"torchrun with --train.device {device.type}: this torch build has no {name} backend; "
                         f"expected a torch with torch.distributed and {name}")
    return name


def start(world: World, device: torch.device) -> None:
    """Join the process group (a no-op in one process)."""
    if not world.distributed:
        return
    name = backend(device)
    if device.type == "cuda":
        torch.cuda.set_device(device)
    dist.init_process_group(name, rank=world.rank, world_size=world.size, timeout=TIMEOUT)


def stop(world: World, finished: bool = False) -> None:
    """Leave the process group. After a finished run every rank first waits for the others, so that no rank tears
    the group down while another still talks to it (a gloo thread left running aborts the process at exit)."""
    if world.distributed and dist.is_initialized():
        if finished:
            dist.barrier()
        dist.destroy_process_group()


def barrier(world: World) -> None:
    if world.distributed:
        dist.barrier()


def mean(world: World, values: torch.Tensor) -> torch.Tensor:
    """The mean over ranks of a tensor of the same shape on every rank."""
    if not world.distributed:
        return values
    values = values.clone()
    dist.all_reduce(values)
    return values / world.size


def mean_losses(world: World, losses: dict, *flags: bool) -> tuple[dict, list[bool]]:
    """The losses of the whole global batch (the mean over ranks), and each flag (such as an interruption): whether
    any rank raised it."""
    if not world.distributed:
        return {k: float(v.detach()) for k, v in losses.items()}, list(flags)
    raised = [losses["loss"].new_tensor(float(flag)) for flag in flags]
    values = mean(world, torch.stack([*(v.detach().float() for v in losses.values()), *raised])).tolist()
    return dict(zip(losses, values[:len(losses)])), [v > 0 for v in values[len(losses):]]


def agree(world: World, device: torch.device):
    """The plan's numbers every rank takes: their mean over the ranks, rounded."""
    def averaged(values: tuple) -> tuple:
        if not world.distributed:
            return values
        means = mean(world, torch.tensor([float(v) for v in values], device=device))
        return tuple(int(round(float(v))) for v in means)
    return averaged
