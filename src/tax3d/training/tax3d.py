"""TAX3D's part in the training loop: the model and its EMA, AdamW, the batches and diffusion noise, the loss
(under DistributedDataParallel and autocast where asked), validation with best/ and steps/, and last/."""

from __future__ import annotations

import copy
import math
import time
from pathlib import Path

import torch
from torch import nn
from torch.nn.parallel import DistributedDataParallel
from torch.utils.data import DataLoader

from tax3d import config as cfg
from tax3d import extent
from tax3d.checkpoint import STATE_NAME, read_weights, save_checkpoint
from tax3d.data.dataset import DemoDataset
from tax3d.errors import UsageError
from tax3d.model.tax3d import CheckpointError, Tax3D
from tax3d.training.batches import EpochItems, StepBatches
from tax3d.training.budget import Plan
from tax3d.training.distributed import World
from tax3d.training.interrupt import ignore_interrupts
from tax3d.training.validation import validate


def ema_decay(step: int, decay: float) -> float:
    """The EMA's decay after optimizer step `step` (0-based): min(decay, (1 + step) / (10 + step)), a warm-up as in
    TensorFlow's ExponentialMovingAverage with num_updates, so the average forgets the initial weights early."""
    return min(decay, (1.0 + step) / (10.0 + step))


class Tax3DLearner:
    name = "train"

    def __init__(self, config: cfg.Config, out: Path, dataset: DemoDataset, val_demos: list[dict],
                 device: torch.device, dtype: torch.dtype | None, world: World):
        c = self.train = config.train
        self.config, self.out, self.dataset, self.val_demos, self.device, self.dtype, self.world = (
            config, out, dataset, val_demos, device, dtype, world)
        torch.manual_seed(c.seed)
        self.model = Tax3D(config).to(device)
        self.model.extent = extent.of_scenes((action.numpy(), anchor.numpy()) for action, anchor, _ in dataset.demos)
        self.ema = copy.deepcopy(self.model.net).requires_grad_(False) if c.ema > 0 else None
        self.optimizer = torch.optim.AdamW(self.model.parameters(), lr=c.lr, weight_decay=c.weight_decay)
        self.noise_gen = torch.Generator(device=device).manual_seed(c.seed)  # diffusion timesteps and noise
        self.plan = Plan.of(c)
        self.grad_clip, self.best, self.share = c.grad_clip, math.inf, world.share(c.batch_size)
        self.model.train()

    def load(self, last: Path) -> tuple[int, float]:
        """Model, optimizer, EMA, plan, generators and best RMSE from last/; the step and elapsed seconds."""
        read_weights(last)  # the checkpoint's own weights must be readable too, not only the state
        try:
            state = torch.load(last / STATE_NAME, map_location=self.device, weights_only=True)
            missing = [k for k in ("model", "optimizer", "step", "best", "elapsed", "noise_rng", "torch_rng")
                       if k not in state]
        except Exception as err:  # torch.load raises several types for a truncated or foreign file
            raise CheckpointError(f"{last / STATE_NAME}: unreadable training state ({str(err).split('. ')[0]}); "
                                  f"expected the file written with {last / 'model.safetensors'}") from None
        if missing:
            raise CheckpointError(f"{last / STATE_NAME}: no {missing[0]} in the training state")
        self.model.load_weights(state["model"], str(last / STATE_NAME))
        self.optimizer.load_state_dict(state["optimizer"])
        if self.ema is not None:
            self.ema.load_state_dict(state["ema"] if "ema" in state else state["model"])
        # earlier versions kept the plan's knee in config.json (train.replan_step, train.replan_progress)
        retired = cfg.read_json(last / "config.json").get("train", {})
        self.plan.load_state_dict(state.get("plan", {"knee": retired.get("replan_step", 0),
                                                     "knee_progress": retired.get("replan_progress", 0.0)}))
        self.noise_gen.set_state(state["noise_rng"].cpu())  # a CPU ByteTensor, for CUDA too (ATen check_rng_state)
        torch.set_rng_state(state["torch_rng"].cpu())
        self.best = float(state["best"])
        return int(state["step"]), float(state["elapsed"])

    def save_config(self, path: Path) -> None:
        cfg.save(self.config, path)

    def planned(self, plan: Plan) -> None:
        self.train.steps, self.train.val_every = plan.steps, plan.val_every

    def batches(self, step: int):
        """The batches from `step` on; the loss function is made here, after the weights are loaded (DDP copies
        rank 0's)."""
        c, world = self.train, self.world
        self.loss_fn = training_loss(self.model, self.dtype, self.device, world)
        if c.compile:
            self.loss_fn = torch.compile(self.loss_fn)
        sampler = StepBatches(len(self.dataset), c.batch_size, c.seed, step, world.rank, world.size)
        return iter(DataLoader(EpochItems(self.dataset), batch_sampler=sampler, num_workers=c.num_workers,
                               persistent_workers=c.num_workers > 0, worker_init_fn=ignore_interrupts))

    def loss(self, batch: dict, step: int) -> dict:
        batch = {k: v.to(self.device) for k, v in batch.items()}
        size = self.train.batch_size
        # every rank draws the timesteps and noise of the whole global batch and keeps its own rows
        t = self.model.diffusion.sample_timesteps(size, self.device, self.noise_gen)[self.share]
        noise = torch.randn((size, *batch["target"].shape[1:]), generator=self.noise_gen, device=self.device)
        return self.loss_fn(batch, t, noise[self.share])

    def average(self, step: int) -> None:
        if self.ema is not None:
            decay = ema_decay(step, self.train.ema)
            with torch.no_grad():
                for e, p in zip(self.ema.parameters(), self.model.net.parameters()):
                    e.lerp_(p, 1.0 - decay)

    def weights(self) -> dict:
        return (self.ema if self.ema is not None else self.model.net).state_dict()

    def evaluated(self) -> Tax3D:
        model = copy.deepcopy(self.model)
        model.net.load_state_dict(self.weights())
        return model

    def validate(self, step: int) -> dict:
        """The validation record; best/ when it is the lowest RMSE yet, and steps/STEP at keep_every."""
        c, out = self.train, self.out
        record = {}
        if self.val_demos:
            record = validate(self.evaluated(), self.val_demos, c.val_samples, seed=c.seed, points=c.val_points)
            if record["val_rmse"] < self.best:
                self.best = record["val_rmse"]
                save_checkpoint(out, "best", self.model, self.weights(), None)
        if c.keep_every and step % c.keep_every == 0:
            (out / "steps").mkdir(exist_ok=True)
            save_checkpoint(out / "steps", str(step), self.model, self.weights(), None)
        return record

    def time_validation(self) -> float:
        if not (self.world.main and self.val_demos):
            return 0.0
        evaluated = self.evaluated()
        began = time.time()
        validate(evaluated, self.val_demos, self.train.val_samples, seed=self.train.seed, points=self.train.val_points)
        return time.time() - began

    def save_last(self, step: int, elapsed: float) -> None:
        state = {"model": self.model.net.state_dict(), "optimizer": self.optimizer.state_dict(), "step": step,
                 "best": self.best, "elapsed": elapsed, "noise_rng": self.noise_gen.get_state(),
                 "torch_rng": torch.get_rng_state(), "plan": self.plan.state_dict()}
        if self.ema is not None:
            state["ema"] = self.ema.state_dict()
        save_checkpoint(self.out, "last", self.model, self.weights(), state)


# --- the loss --------------------------------------------------------------------------------------------------


def float_output(module: nn.Module, args, output: torch.Tensor) -> torch.Tensor:
    """The network's output as fp32, so that the diffusion maths after it (vb terms, logs, exps) run in fp32."""
    return output.float()


class TrainingLoss(nn.Module):
    """model.loss as a module, so that DistributedDataParallel can wrap it; under autocast to dtype when given."""

    def __init__(self, model: Tax3D, dtype: torch.dtype | None, device: torch.device):
        super().__init__()
        self.model, self.dtype, self.device_type = model, dtype, device.type
        if dtype is not None:
            model.net.register_forward_hook(float_output)

    def forward(self, batch: dict, t: torch.Tensor, noise: torch.Tensor) -> dict:
        if self.dtype is None:
            return self.model.loss(batch, t, noise)
        # autocast lowers only its listed ops (linear, matmul, attention); the diffusion code has none of them
        with torch.autocast(self.device_type, dtype=self.dtype):
            return self.model.loss(batch, t, noise)


def training_loss(model: Tax3D, dtype: torch.dtype | None, device: torch.device, world: World):
    loss = TrainingLoss(model, dtype, device)
    if not world.distributed:
        return loss
    return DistributedDataParallel(loss, device_ids=[device.index] if device.type == "cuda" else None)


def native_bf16(device: torch.device) -> bool:
    with torch.cuda.device(device):
        try:
            return torch.cuda.is_bf16_supported(including_emulation=False)
        except TypeError:  # older torch has no including_emulation argument
            return torch.cuda.is_bf16_supported()


def pick_precision(name: str, device: torch.device) -> torch.dtype | None:
    """The autocast dtype of the network's forward: None for fp32."""
    if name == "fp32":
        return None
    if name != "bf16":
        raise UsageError(f"--train.precision {name!r}: expected fp32 or bf16")
    if device.type == "cuda" and not native_bf16(device):
        raise UsageError(f"--train.precision bf16: {device} has no native bfloat16 support; expected "
                         f"--train.precision fp32 on this GPU")
    return torch.bfloat16
