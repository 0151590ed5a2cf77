"""`tax3d train-dp3`: fit the DP3 baseline on demos with trajectories (`tax3d generate --trajectories`).

    tax3d train-dp3 --preset cpu --data.train data/demos/train --out runs/dp3 [--train.steps 2000]

The options are the dotted config fields of `tax3d train` (`--model.*`, `--diffusion.*`, `--data.*`, `--train.*`).

OUT gets config.json, log.jsonl (one line per step) and last/: a checkpoint directory (config.json and
model.safetensors, the EMA weights, for `tax3d eval --checkpoint OUT/last`) plus training_state.pt to resume from.
A run whose OUT already holds last/ continues from it, if it is the same run (tax3d.rerun: the same options and
demos; --fresh starts afresh); the run holds OUT's lock (tax3d.runlock) while it writes there. Each step's batch, rotations, diffusion steps and noise come
from a generator seeded by (seed, step), so a resumed run sees what an uninterrupted one would. A `--train.minutes`
run is planned as `tax3d train` plans one (tax3d.plan), with each save of last/ in the place of a validation: the
first steps fix train.steps, and every save times it again.
"""

from __future__ import annotations

import copy
import json
import math
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Annotated, Literal, Optional

import numpy as np
import torch

from tax3d import rerun, runlock
from tax3d.atomic import write_text
from tax3d.baselines.dp3 import config as cfg
from tax3d.baselines.dp3.dataset import TrajectoryDataset, rotate_batch
from tax3d.baselines.dp3.model import DP3
from tax3d.data.dataset import demo_files
from tax3d.data.format import data_task
from tax3d.devices import machine_preset, pick_device
from tax3d.errors import UsageError
from tax3d.options import OutputFolder
from tax3d.plan import Plan, timing_step
from tax3d.checkpoint import STATE_NAME, save_checkpoint, truncate_log

ADAM_BETAS = (0.95, 0.999)  # DP3's optimiser settings (docs/dp3.md)
EMA_POWER, EMA_MAX = 0.75, 0.9999  # DP3's EMA: decay 1 - (1 + step)^-0.75, capped


@dataclass
class Args:
    """Train the DP3 baseline. Options left out take the preset's value (or, when resuming, the run's)."""

    out: Annotated[str, OutputFolder] = "runs/dp3"
    """output folder: config.json, log.jsonl and last/"""
    preset: Optional[Literal["paper", "cpu"]] = None
    """paper: docs/reference.md's DP3 (a GPU's work); cpu: a small model that trains in minutes on a CPU; default:
    paper where CUDA is available, else cpu (as `tax3d train`)"""
    device: str = "auto"
    """auto (cuda when available), cpu or cuda"""
    resume: bool = False
    """require a checkpoint in OUT/last to continue from (without it, one is used when present); with it,
    --train.steps and --train.save-every may move the run's end"""
    fresh: bool = False
    """start afresh in OUT: its checkpoints and log are replaced (without it, a rerun into a run's folder resumes
    that run, and only with that run's configuration and demonstrations)"""
    model: cfg.ModelOverrides = field(default_factory=cfg.ModelOverrides)
    diffusion: cfg.DiffusionOverrides = field(default_factory=cfg.DiffusionOverrides)
    data: cfg.DataOverrides = field(default_factory=cfg.DataOverrides)
    train: cfg.TrainOverrides = field(default_factory=cfg.TrainOverrides)


def ema_decay(step: int) -> float:
    """The EMA decay after `step` optimiser steps: 0 at first, so early averages follow the weights."""
    return 0.0 if step <= 0 else min(EMA_MAX, 1.0 - (1.0 + step) ** -EMA_POWER)


def resolve_config(args: Args, out: Path, last: Path | None) -> cfg.DP3Config:
    """The preset with the given options applied; resuming, the run's saved config (its planned steps kept), which
    the command's must equal (tax3d.rerun)."""
    overrides = dict(model=args.model, diffusion=args.diffusion, data=args.data, train=args.train)
    return rerun.resolve(cfg, cfg.preset(default_preset(args.preset)), overrides, out, last, args.resume)


def default_preset(name: str | None) -> str:
    return machine_preset(name, "cpu")


def step_batch(dataset: TrajectoryDataset, config: cfg.DP3Config, step: int, device: torch.device) -> tuple:
    """(batch, t, noise) of one step, all drawn from a generator seeded by (seed, step)."""
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


def run(args: Args) -> int:
    with runlock.hold(Path(args.out)):
        return run_locked(args)


def run_locked(args: Args) -> int:
    from tqdm.auto import tqdm

    out = Path(args.out)
    last = rerun.checkpoint_to_resume(out, args.resume, args.fresh)
    config = resolve_config(args, out, last)
    c = config.train
    if c.threads > 0:
        torch.set_num_threads(c.threads)
    device = pick_device(args.device)
    if not config.data.train:
        raise UsageError("--data.train: no demonstration folder given; expected folders of demos written with "
                         "`tax3d generate --trajectories`")
    train_files = demo_files(config.data.train)
    config.data.task = data_task(train_files, config.data.task)
    digests = rerun.demo_digests(train_files, [])
    if last is not None:
        rerun.check_same_demos(out, digests)
    m = config.model
    dataset = TrajectoryDataset(config.data.train, m.horizon, m.n_obs_steps, config.data.num_action_points,
                                config.data.num_anchor_points)

    torch.manual_seed(c.seed)
    model = DP3(config)
    model.fit_normalizers(*dataset.normalizer_data())
    model.to(device)
    ema = copy.deepcopy(model).requires_grad_(False)
    ema.config = config  # the run's own, so that last/ records the plan's steps
    optimizer = torch.optim.AdamW(model.parameters(), lr=c.lr, betas=ADAM_BETAS, weight_decay=c.weight_decay)
    plan = Plan(c.lr, c.warmup_steps, c.steps, c.save_every, c.minutes)
    step, elapsed = 0, 0.0
    if last is not None:
        state = torch.load(last / STATE_NAME, map_location=device, weights_only=True)
        model.load_weights(state["model"], str(last / STATE_NAME))
        ema.load_weights(state["ema"], str(last / STATE_NAME))
        optimizer.load_state_dict(state["optimizer"])
        step, elapsed = int(state["step"]), float(state["elapsed"])
        plan.load_state_dict(state.get("plan", {}))
        print(f"resuming {out} at step {step}", file=sys.stderr)
        truncate_log(out / "log.jsonl", step)
    if args.fresh:
        rerun.clear_run(out)
    if last is None or not (out / rerun.DIGEST_NAME).is_file():
        rerun.keep_digests(out, digests)
    write_text(out / "config.json", cfg.dumps(config))

    log = open(out / "log.jsonl", "a")
    bar = tqdm(total=c.steps, initial=step, desc="train-dp3", dynamic_ncols=True)
    model.train()
    started = time.time() - elapsed
    plan.resume(step)
    if c.minutes > 0 and step < timing_step(c.warmup_steps):  # a planned run lasts until its first steps are timed
        c.steps = plan.steps = max(c.steps, timing_step(c.warmup_steps))

    def planned(message: str) -> None:
        """The plan's steps into the configuration, config.json and the bar."""
        c.steps, bar.total = plan.steps, plan.steps
        c.save_every = min(c.save_every, c.steps)
        write_text(out / "config.json", cfg.dumps(config))
        print(message, file=sys.stderr)

    while step < c.steps:
        plan.start_step(step)
        batch, t, noise = step_batch(dataset, config, step, device)
        lr = plan.lr_at(step)
        for group in optimizer.param_groups:
            group["lr"] = lr
        loss = model.loss(batch, t, noise)
        optimizer.zero_grad(set_to_none=True)
        loss.backward()
        optimizer.step()
        step += 1
        with torch.no_grad():
            decay = ema_decay(step)
            for e, p in zip(ema.parameters(), model.parameters()):
                e.lerp_(p, 1.0 - decay)
        bar.update(1)
        record = {"step": step, "loss": float(loss.detach()), "lr": lr}
        if c.minutes > 0 and plan.timing(step):
            record["plan"] = plan.make(step, started, lambda: 0.0)
            planned(f"planned {plan.steps} steps for {c.minutes:g} minutes ({plan.step_seconds:.3f} s per step)")
        if step % c.save_every == 0 or step == c.steps:
            replan = plan.retime(step, started, time.time())  # before the save, so that a resumed run keeps it
            if replan is not None:
                record["replan"] = replan
                planned(f"re-planned {plan.steps} steps for {c.minutes:g} minutes ({plan.step_seconds:.3f} s per "
                        f"step since the last timing)")
            state = {"model": model.state_dict(), "ema": ema.state_dict(), "optimizer": optimizer.state_dict(),
                     "step": step, "elapsed": time.time() - started, "plan": plan.state_dict()}
            save_checkpoint(out, "last", ema, ema.state_dict(), state)
            bar.set_postfix(loss=f"{record['loss']:.4f}")
        record["seconds"] = round(time.time() - started, 2)
        log.write(json.dumps(record) + "\n")
        log.flush()
    bar.close()
    log.close()
    return 0


if __name__ == "__main__":
    import tyro

    sys.exit(run(tyro.cli(Args)))
