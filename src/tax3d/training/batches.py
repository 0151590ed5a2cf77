"""What each step trains on: TAX3D's batches from a stream of epochs, and DP3's batch drawn from (seed, step). A
resumed run sees exactly the batches it would have seen without the interruption."""

from __future__ import annotations

import math

import numpy as np
import torch
from torch.utils.data import Dataset, Sampler

from tax3d.baselines.dp3.dataset import TrajectoryDataset, rotate_batch
from tax3d.data.dataset import DemoDataset
from tax3d.training.distributed import World


class StepBatches(Sampler):
    """Batches of (epoch, index) pairs from a stream of per-epoch permutations, starting at a given step.

    Batch s holds stream positions s * B .. (s + 1) * B - 1. With world_size W, rank r gets rows r * B / W ..
    (r + 1) * B / W - 1 of each batch: together the ranks see the batches of one process."""

    def __init__(self, size: int, batch_size: int, seed: int, start_step: int = 0, rank: int = 0,
                 world_size: int = 1):
        self.size, self.batch_size, self.seed, self.start_step = size, batch_size, seed, start_step
        self.share = World(rank, world_size).share(batch_size)

    def permutation(self, epoch: int) -> list[int]:
        generator = torch.Generator().manual_seed(int(np.random.SeedSequence([self.seed, epoch]).generate_state(1)[0]))
        return torch.randperm(self.size, generator=generator).tolist()

    def __iter__(self):
        position = self.start_step * self.batch_size
        epoch, order = -1, []
        while True:
            batch = []
            for _ in range(self.batch_size):
                e, i = divmod(position, self.size)
                if e != epoch:
                    epoch, order = e, self.permutation(e)
                batch.append((e, order[i]))
                position += 1
            yield batch[self.share]


class EpochItems(Dataset):
    """Item (epoch, index) of a DemoDataset: the sample it gives at that epoch."""

    def __init__(self, dataset: DemoDataset):
        self.dataset = dataset

    def __len__(self) -> int:
        return len(self.dataset)

    def __getitem__(self, key):
        epoch, index = key
        self.dataset.set_epoch(epoch)
        return self.dataset[index]


def dp3_batch(dataset: TrajectoryDataset, config, step: int, device: torch.device) -> tuple:
    """DP3's (batch, t, noise) of one step, all drawn from a generator seeded by (seed, step)."""
    seed = int(np.random.SeedSequence([config.train.seed, step]).generate_state(1)[0])
    generator = torch.Generator().manual_seed(seed)
    size = config.train.batch_size
    rows = [dataset[int(i)] for i in torch.randint(len(dataset), (size,), generator=generator)]
    batch = {k: torch.stack([r[k] for r in rows]) for k in rows[0]}
    angles = torch.rand(size, generator=generator, dtype=torch.float64) * 2 * math.pi
    if config.data.rotate:
        batch = rotate_batch(batch, angles.float())
    t = torch.randint(config.diffusion.train_steps, (size,), generator=generator)
    noise = torch.randn(batch["action"].shape, generator=generator)
    return {k: v.to(device) for k, v in batch.items()}, t.to(device), noise.to(device)
