"""DP3's part in the training loop: the model and its EMA (DP3's rule), AdamW with DP3's betas, each step's batch
drawn from (seed, step), no validation (each validation point only saves last/, the EMA weights for `tax3d eval`)."""

from __future__ import annotations

import copy
from pathlib import Path

import torch

from tax3d.atomic import write_text
from tax3d.baselines.dp3 import config as cfg
from tax3d.baselines.dp3.dataset import TrajectoryDataset
from tax3d.baselines.dp3.model import DP3
from tax3d.checkpoint import STATE_NAME, save_checkpoint
from tax3d.training import batches
from tax3d.training.budget import Plan

ADAM_BETAS = (0.95, 0.999)  # DP3's optimiser settings (docs/dp3.md)
EMA_POWER, EMA_MAX = 0.75, 0.9999  # DP3's EMA: decay 1 - (1 + step)^-0.75, capped


def ema_decay(step: int) -> float:
    """The EMA decay after `step` optimiser steps: 0 at first, so early averages follow the weights."""
    return 0.0 if step <= 0 else min(EMA_MAX, 1.0 - (1.0 + step) ** -EMA_POWER)


class DP3Learner:
    name = "train-dp3"
    grad_clip = 0.0

    def __init__(self, config: cfg.DP3Config, out: Path, dataset: TrajectoryDataset, device: torch.device):
        c = self.train = config.train
        self.config, self.out, self.dataset, self.device = config, out, dataset, device
        torch.manual_seed(c.seed)
        self.model = DP3(config)
        self.model.fit_normalizers(*dataset.normalizer_data())
        self.model.to(device)
        self.ema = copy.deepcopy(self.model).requires_grad_(False)
        self.ema.config = config  # the run's own, so that last/ records the plan's steps
        self.optimizer = torch.optim.AdamW(self.model.parameters(), lr=c.lr, betas=ADAM_BETAS,
                                           weight_decay=c.weight_decay)
        self.plan = Plan(c.lr, c.warmup_steps, c.steps, c.save_every, c.minutes)
        self.model.train()

    def load(self, last: Path) -> tuple[int, float]:
        state = torch.load(last / STATE_NAME, map_location=self.device, weights_only=True)
        self.model.load_weights(state["model"], str(last / STATE_NAME))
        self.ema.load_weights(state["ema"], str(last / STATE_NAME))
        self.optimizer.load_state_dict(state["optimizer"])
        self.plan.load_state_dict(state.get("plan", {}))
        return int(state["step"]), float(state["elapsed"])

    def save_config(self, path: Path) -> None:
        write_text(path, cfg.dumps(self.config))

    def planned(self, plan: Plan) -> None:
        self.train.steps = plan.steps
        self.train.save_every = min(self.train.save_every, plan.steps)

    def batches(self, step: int):
        while True:
            yield batches.dp3_batch(self.dataset, self.config, step, self.device)
            step += 1

    def loss(self, batch: tuple, step: int) -> dict:
        return {"loss": self.model.loss(*batch)}

    def average(self, step: int) -> None:
        decay = ema_decay(step + 1)
        with torch.no_grad():
            for e, p in zip(self.ema.parameters(), self.model.parameters()):
                e.lerp_(p, 1.0 - decay)

    def validate(self, step: int) -> dict:
        return {}

    def time_validation(self) -> float:
        return 0.0

    def save_last(self, step: int, elapsed: float) -> None:
        state = {"model": self.model.state_dict(), "ema": self.ema.state_dict(),
                 "optimizer": self.optimizer.state_dict(), "step": step, "elapsed": elapsed,
                 "plan": self.plan.state_dict()}
        save_checkpoint(self.out, "last", self.ema, self.ema.state_dict(), state)
