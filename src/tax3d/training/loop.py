"""The training loop of TAX3D and DP3 alike; what differs between them is the learner (training/tax3d.py,
training/dp3.py): its model, optimizer, batches, loss, EMA, validation and saved state."""

from __future__ import annotations

import sys
import time
from pathlib import Path

import torch
from tqdm.auto import tqdm

from tax3d.checkpoint import RunLog, truncate_log
from tax3d.errors import UsageError
from tax3d.training import distributed
from tax3d.training.budget import Budget
from tax3d.training.interrupt import Interruption, stop_workers


def fit(learner, out: Path, last: Path | None, world: distributed.World, interruption: Interruption, ending) -> int:
    """Train `learner` in OUT from last/ (None: from the start) until its plan's last step; returns that step. An
    interruption saves last/ at the end of its step and raises KeyboardInterrupt."""
    step, elapsed = learner.load(last) if last is not None else (0, 0.0)
    if last is not None and world.main:
        print(f"resuming {out} at step {step}", file=sys.stderr)
        truncate_log(out / "log.jsonl", step)
    if world.main:
        out.mkdir(parents=True, exist_ok=True)
        learner.save_config(out / "config.json")
    batches = learner.batches(step)
    ending.callback(stop_workers, batches)  # an error anywhere ends the data workers before OUT's lock is released
    log = RunLog(out / "log.jsonl", append=last is not None) if world.main else None
    plan = learner.plan
    unplanned = plan.minutes > 0 and plan.step_seconds == 0  # no total (and no ETA) until the plan fixes the steps
    bar = tqdm(total=None if unplanned else plan.steps, initial=step, desc=learner.name, dynamic_ncols=True,
               disable=not world.main)
    ending.callback(bar.close)
    started = time.time() - elapsed

    def planned(message: str) -> None:
        """The plan's steps into the configuration, config.json and the bar."""
        learner.planned(plan)
        bar.total = plan.steps
        if world.main:
            learner.save_config(out / "config.json")
            print(message, file=sys.stderr)

    budget = Budget(plan, learner.time_validation, distributed.agree(world, learner.device), planned, world.main)
    budget.start(step)
    interrupted = False
    while step < plan.steps:
        lr = budget.lr(step)
        for group in learner.optimizer.param_groups:
            group["lr"] = lr
        losses = learner.loss(next(batches), step)
        if not torch.isfinite(losses["loss"].detach()):
            bar.close()
            raise UsageError(f"--out {out}: the training loss is {float(losses['loss'].detach()):g} at step {step + 1}; "
                             f"expected a finite loss (lower --train.lr, or check the demos); "
                             f"the checkpoints there are from before it")
        learner.optimizer.zero_grad(set_to_none=True)
        losses["loss"].backward()
        if learner.grad_clip > 0:
            torch.nn.utils.clip_grad_norm_(learner.model.parameters(), learner.grad_clip)
        learner.optimizer.step()
        learner.average(step)
        step += 1
        bar.update(1)

        values, (interrupted,) = distributed.mean_losses(world, losses, interruption.requested)
        record = {"step": step, **values, "lr": lr, **budget.timed(step, started)}
        validating = step % plan.val_every == 0 or step == plan.steps
        if validating:
            val_started = time.time()
            if world.main:
                record.update(learner.validate(step))
                bar.set_postfix(shown(record))
            distributed.barrier(world)
            record.update(budget.validated(step, started, val_started))
            if world.main:  # after the re-plan, so that a run resumed from here keeps it
                learner.save_last(step, time.time() - started)
        if world.main:
            record["seconds"] = round(time.time() - started, 2)
            log.write(record)
        if interrupted:
            if world.main and not validating:
                learner.save_last(step, time.time() - started)
            break
    bar.close()
    stop_workers(batches)
    if log is not None:
        log.close()
    if interrupted and step < plan.steps:
        if world.main:
            print(f"interrupted at step {step} of {plan.steps}: saved {out / 'last'}; the same command resumes there",
                  file=sys.stderr)
        raise KeyboardInterrupt
    return step


def shown(record: dict) -> dict:
    """The bar's loss and validation RMSE."""
    return {"loss": f"{record['loss']:.4f}", **({"val": f"{record['val_rmse']:.3f}"} if "val_rmse" in record else {})}
