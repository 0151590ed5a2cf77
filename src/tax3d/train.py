"""`tax3d train`: fit a TAX3D variant on demonstration folders.

    tax3d train --preset cpu --out runs/cd --data.train DIR --data.val DIR [--model.variant cp --train.steps 2000]

OUT gets config.json (the resolved configuration), log.jsonl (one line per logged step), last/ (config.json,
model.safetensors and training_state.pt, rewritten atomically at every validation and on Ctrl-C or SIGTERM) and
best/ (the weights with the lowest validation min-of-samples RMSE); at its end, summary.json (the plan, every
validation and the last step: kept JSON of kind "train-log", tax3d.kept). A run whose OUT already holds last/
continues from it; one that starts afresh starts a fresh log.jsonl.

Under torchrun (`torchrun --nproc_per_node N -m tax3d.cli train ...`, docs/scaling.md) each process takes its
share of every global batch, DistributedDataParallel averages the gradients, and rank 0 alone validates and writes.
"""

from __future__ import annotations


import contextlib
import copy
import math
import signal
import sys
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Annotated, Optional

import numpy as np
import torch
from torch import nn
from torch.nn.parallel import DistributedDataParallel
from torch.utils.data import DataLoader, Dataset, Sampler

from tax3d import config as cfg
from tax3d import devices
from tax3d import distributed
from tax3d import extent
from tax3d import kept
from tax3d import provenance
from tax3d import rerun
from tax3d import runlock
from tax3d.atomic import write_json
from tax3d.checkpoint import (STATE_NAME, RunLog, read_log, read_weights, save_checkpoint,
                              truncate_log)
from tax3d.data.dataset import DemoDataset, demo_files
from tax3d.data.format import data_task, grip_vertices, load_demo
from tax3d.errors import UsageError
from tax3d.metrics import coverage_rmse, grip_error, min_of_samples_rmse, precision_rmse, rmse
from tax3d.model.tax3d import CheckpointError, Tax3D
from tax3d.options import OutputFolder
from tax3d.plan import Plan

LONG_RUN_HOURS = 12  # a run planned longer than this is told so at its start


@dataclass
class Args:
    """Train a TAX3D variant. Options left out take the preset's value (or, when resuming, the run's)."""

    out: Annotated[str, OutputFolder] = "runs/tax3d"
    """output folder: config.json, log.jsonl, last/ and best/ checkpoints"""
    preset: Optional[cfg.PresetName] = None
    """paper: the paper's settings (a GPU's work); cpu: the recipe that learns on one CPU core (cloths and the bag,
    the table's rows); cpu-multimodal: cpu with the x_0 loss, for two-hole cloths; cpu-fast: cpu's quality in half
    its minutes (cloths and the bag); default: paper where CUDA is available, else cpu-fast"""
    resume: bool = False
    """require a checkpoint in OUT/last to continue from (without it, one is used when present); with it,
    --train.steps and --train.val-every may move the run's end (the schedule then ends there)"""
    fresh: bool = False
    """start afresh in OUT: its checkpoints, log and summary are replaced (without it, a rerun into a run's folder
    resumes that run, and only with that run's configuration and demonstrations)"""
    model: cfg.ModelOverrides = field(default_factory=cfg.ModelOverrides)
    diffusion: cfg.DiffusionOverrides = field(default_factory=cfg.DiffusionOverrides)
    data: cfg.DataOverrides = field(default_factory=cfg.DataOverrides)
    train: cfg.TrainOverrides = field(default_factory=cfg.TrainOverrides)


# --- the EMA and batches ---------------------------------------------------------------------------------


def ema_decay(step: int, decay: float) -> float:
    """The EMA's decay after optimizer step `step` (0-based): min(decay, (1 + step) / (10 + step)), a warm-up as in
    TensorFlow's ExponentialMovingAverage with num_updates, so the average forgets the initial weights early."""
    return min(decay, (1.0 + step) / (10.0 + step))


class StepBatches(Sampler):
    """Batches of (epoch, index) pairs from a stream of per-epoch permutations, starting at a given step.

    Batch s holds stream positions s * B .. (s + 1) * B - 1, so a resumed run sees exactly the batches it would
    have seen without the interruption. With world_size W, rank r gets rows r * B / W .. (r + 1) * B / W - 1 of
    each batch: together the ranks see the batches of one process."""

    def __init__(self, size: int, batch_size: int, seed: int, start_step: int = 0, rank: int = 0,
                 world_size: int = 1):
        self.size, self.batch_size, self.seed, self.start_step = size, batch_size, seed, start_step
        self.share = distributed.World(rank, world_size).share(batch_size)

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


# --- validation ------------------------------------------------------------------------------------------------


def load_val_demos(config: cfg.Config) -> list[dict]:
    if not config.data.val:
        return []
    files = demo_files(config.data.val)
    if config.train.val_demos > 0:
        files = files[: config.train.val_demos]
    return [load_demo(path) for path in files]


def validate(model: Tax3D, demos: list[dict], num_samples: int, seed: int, steps: int | None = None,
             points: str = "whole") -> dict:
    """World-frame RMSE on whole action clouds: the mean over demos of the min over samples, and over all samples;
    val_grip_error: the mean over demos and samples of the distance at the grasped vertices (where the policy's
    grippers go); where demos share an observation (one per mode), also the coverage and precision RMSE over those
    groups (appendix C)."""
    was_training = model.training
    model.eval()
    scenes = [(d["action_pc"], d["anchor_pc"]) for d in demos]
    predictions = model.predict_scenes(scenes, num_samples=num_samples, steps=steps, seed=seed,
                                       max_points=0 if points == "whole" else None)
    model.train(was_training)
    goals = [d["action_pc"] + d["flow"] for d in demos]
    best = [float(min_of_samples_rmse(p, g)) for p, g in zip(predictions, goals)]
    every = [float(rmse(p, g).mean()) for p, g in zip(predictions, goals)]
    record = {"val_rmse": float(np.mean(best)), "val_rmse_mean": float(np.mean(every))}
    grip = [grip_vertices(d) for d in demos]
    if all(grip):
        record["val_grip_error"] = float(np.mean([grip_error(p, g, v) for p, g, v in zip(predictions, goals, grip)]))
    groups = scene_groups(scenes)
    if any(len(g) > 1 for g in groups):
        pooled = [(np.concatenate([predictions[i] for i in g]), np.stack([goals[i] for i in g])) for g in groups]
        record["val_coverage_rmse"] = float(np.mean([coverage_rmse(p, g) for p, g in pooled]))
        record["val_precision_rmse"] = float(np.mean([precision_rmse(p, g) for p, g in pooled]))
    return record


def scene_groups(scenes: list[tuple[np.ndarray, np.ndarray]]) -> list[list[int]]:
    """Indices of the demos that share one observation (a multimodal cloth's demo for each hole), in first order."""
    groups: dict[bytes, list[int]] = {}
    for i, (action, anchor) in enumerate(scenes):
        key = np.ascontiguousarray(action).tobytes() + b"|" + np.ascontiguousarray(anchor).tobytes()
        groups.setdefault(key, []).append(i)
    return list(groups.values())


# --- configuration ---------------------------------------------------------------------------------------------


def resolve_config(args: Args, out: Path, last: Path | None) -> cfg.Config:
    """The command's configuration; resuming, the run's (its planned steps kept), which the command's must equal
    (tax3d.rerun), but for the options that change only how the run computes."""
    overrides = dict(model=args.model, diffusion=args.diffusion, data=args.data, train=args.train)
    return rerun.resolve(cfg, cfg.preset(default_preset(args.preset)), overrides, out, last, args.resume)


def config_of_command(argv: list[str]) -> cfg.Config:
    """The configuration a fresh run of `tax3d train ARGV` starts from (before a --train.minutes plan)."""
    import tyro

    return resolve_config(tyro.cli(Args, args=argv, prog="tax3d train"), Path("."), None)


def default_preset(name: str | None) -> str:
    return devices.machine_preset(name, "cpu-fast")


def pick_device(name: str) -> torch.device:
    return devices.pick_device(name, "--train.device")


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


def training_loss(model: Tax3D, dtype: torch.dtype | None, device: torch.device, world: distributed.World):
    loss = TrainingLoss(model, dtype, device)
    if not world.distributed:
        return loss
    return DistributedDataParallel(loss, device_ids=[device.index] if device.type == "cuda" else None)


def mean_losses(world: distributed.World, losses: dict, *flags: bool) -> tuple[dict, list[bool]]:
    """The losses of the whole global batch (the mean over ranks), and each flag (out of time, interrupted): whether
    any rank raised it."""
    if not world.distributed:
        return {k: float(v.detach()) for k, v in losses.items()}, list(flags)
    raised = [losses["loss"].new_tensor(float(flag)) for flag in flags]
    values = distributed.mean(world, torch.stack([*(v.detach().float() for v in losses.values()), *raised])).tolist()
    return dict(zip(losses, values[:len(losses)])), [v > 0 for v in values[len(losses):]]


class Interruption:
    """Ctrl-C (SIGINT) or SIGTERM (a scheduler preempting the job, a `kill`) during training, deferred: the first
    sets `requested`, and the loop writes last/ and stops at the end of its step; a second interrupts at once.
    Installed in the main thread only."""

    SIGNALS = (signal.SIGINT, signal.SIGTERM)

    def __init__(self):
        self.requested, self.previous = False, {}

    def __enter__(self) -> "Interruption":
        if threading.current_thread() is threading.main_thread():
            self.previous = {s: signal.signal(s, self.handle) for s in self.SIGNALS}
        return self

    def __exit__(self, *exc) -> None:
        for s, handler in self.previous.items():
            signal.signal(s, handler)

    def handle(self, signum, frame) -> None:
        if self.requested:
            raise KeyboardInterrupt
        self.requested = True
        print(f"\n{signal.Signals(signum).name}: stopping after this step to save last/ (again to stop at once)",
              file=sys.stderr)


def stop_workers(batches) -> None:
    """End a DataLoader iterator's worker processes now, not in the interpreter's exit: a worker ignores SIGTERM
    (ignore_interrupts), so the exit's terminate-and-join of child processes would wait for it forever."""
    if hasattr(batches, "_shutdown_workers"):
        batches._shutdown_workers()


def ignore_interrupts(worker_id: int) -> None:
    """A data worker leaves Ctrl-C and SIGTERM to the training loop (which stops after its step, then ends the
    workers)."""
    for s in Interruption.SIGNALS:
        signal.signal(s, signal.SIG_IGN)


# --- the loop --------------------------------------------------------------------------------------------------


def load_state(last: Path, model: Tax3D, optimizer, ema, plan: Plan, noise_gen, device) -> tuple[int, float, float]:
    """Restore model, optimizer, EMA, plan and generators from last/; returns step, best and elapsed seconds."""
    read_weights(last)  # the checkpoint's own weights must be readable too, not only the state
    try:
        state = torch.load(last / STATE_NAME, map_location=device, weights_only=True)
        missing = [k for k in ("model", "optimizer", "step", "best", "elapsed", "noise_rng", "torch_rng")
                   if k not in state]
    except Exception as err:  # torch.load raises several types for a truncated or foreign file
        raise CheckpointError(f"{last / STATE_NAME}: unreadable training state ({str(err).split('. ')[0]}); "
                              f"expected the file written with {last / 'model.safetensors'}") from None
    if missing:
        raise CheckpointError(f"{last / STATE_NAME}: no {missing[0]} in the training state")
    model.load_weights(state["model"], str(last / STATE_NAME))
    optimizer.load_state_dict(state["optimizer"])
    if ema is not None:
        ema.load_state_dict(state["ema"] if "ema" in state else state["model"])
    # earlier versions kept the plan's knee in config.json (train.replan_step, train.replan_progress)
    retired = cfg.read_json(last / "config.json").get("train", {})
    plan.load_state_dict(state.get("plan", {"knee": retired.get("replan_step", 0),
                                            "knee_progress": retired.get("replan_progress", 0.0)}))
    noise_gen.set_state(state["noise_rng"].cpu())  # a CPU ByteTensor, for CUDA generators too (ATen check_rng_state)
    torch.set_rng_state(state["torch_rng"].cpu())
    return int(state["step"]), float(state["best"]), float(state["elapsed"])


def run(args: Args) -> int:
    """Train in OUT, holding its lock (tax3d.runlock) until every process of the run has ended."""
    world = distributed.from_env()
    with contextlib.ExitStack() as ending:
        if world.main:
            ending.enter_context(runlock.hold(Path(args.out)))
        return run_locked(args, world, ending)


def run_locked(args: Args, world: distributed.World, ending: contextlib.ExitStack) -> int:
    out = Path(args.out)
    last = rerun.checkpoint_to_resume(out, args.resume, args.fresh)
    config = resolve_config(args, out, last)
    c = config.train
    if not config.data.train:
        raise UsageError("--data.train: no training demonstration folder given")
    train_files, val_files = demo_files(config.data.train), demo_files(config.data.val) if config.data.val else []
    config.data.task = data_task(train_files + val_files, config.data.task)  # what the files name, or "custom"
    digests = rerun.demo_digests(train_files, val_files)
    if last is not None:
        rerun.check_same_demos(out, digests)
    distributed.check_batch_size(world, c.batch_size)
    if c.threads > 0:
        torch.set_num_threads(c.threads)
    # Subnormal floats (below 1.2e-38) take the CPU's slow path; some runs fill with them and step at half speed
    # (benchmarks/subnormal.py, docs/results/training/subnormal-multimodal-64.json). No value that size matters.
    torch.set_flush_denormal(True)
    device = distributed.rank_device(world, c.device, pick_device(c.device))
    dtype = pick_precision(c.precision, device)

    dataset = DemoDataset(config.data.train, config.model.variant, train=True, rotate=config.data.rotate,
                          rotate_scene=config.data.rotate_scene, occlusion=config.data.occlusion,
                          num_action_points=config.data.num_action_points,
                          num_anchor_points=config.data.num_anchor_points, train_size=config.data.train_size,
                          seed=c.seed, subsets=config.data.subsets,
                          grip_weight=config.data.grip_weight)
    val_demos = load_val_demos(config)
    if world.main:
        if args.fresh:
            rerun.clear_run(out)
        if last is None or not (out / rerun.DIGEST_NAME).is_file():
            rerun.keep_digests(out, digests)
    distributed.start(world, device)
    try:
        with Interruption() as interruption:
            code = fit(config, out, last, dataset, val_demos, device, dtype, world, interruption, ending)
    except BaseException:
        distributed.stop(world)
        raise
    distributed.stop(world, finished=True)
    return code


def fit(config: cfg.Config, out: Path, last: Path | None, dataset: DemoDataset, val_demos: list[dict],
        device: torch.device, dtype: torch.dtype | None, world: distributed.World,
        interruption: Interruption | None = None, ending: contextlib.ExitStack | None = None) -> int:
    from tqdm.auto import tqdm

    c = config.train
    torch.manual_seed(c.seed)
    model = Tax3D(config).to(device)
    model.extent = extent.of_scenes((action.numpy(), anchor.numpy()) for action, anchor, _ in dataset.demos)
    ema = copy.deepcopy(model.net).requires_grad_(False) if c.ema > 0 else None
    optimizer = torch.optim.AdamW(model.parameters(), lr=c.lr, weight_decay=c.weight_decay)
    noise_gen = torch.Generator(device=device).manual_seed(c.seed)  # diffusion timesteps and noise
    plan = Plan.of(c)
    step, best, elapsed = 0, float("inf"), 0.0

    if last is not None:
        step, best, elapsed = load_state(last, model, optimizer, ema, plan, noise_gen, device)
        if world.main:
            print(f"resuming {out} at step {step}", file=sys.stderr)
            truncate_log(out / "log.jsonl", step)
    if world.main:
        out.mkdir(parents=True, exist_ok=True)
        cfg.save(config, out / "config.json")

    loss_fn = training_loss(model, dtype, device, world)
    if c.compile:
        loss_fn = torch.compile(loss_fn)
    sampler = StepBatches(len(dataset), c.batch_size, c.seed, step, world.rank, world.size)
    loader = DataLoader(EpochItems(dataset), batch_sampler=sampler, num_workers=c.num_workers,
                        persistent_workers=c.num_workers > 0, worker_init_fn=ignore_interrupts)
    batches = iter(loader)
    if ending is not None:  # an error anywhere ends the data workers before the run's lock is released
        ending.callback(stop_workers, batches)
    log = RunLog(out / "log.jsonl", append=last is not None) if world.main else None
    # a --train.minutes run shows no total (and no ETA) until its plan fixes the steps
    unplanned = c.minutes > 0 and plan.step_seconds == 0
    bar = tqdm(total=None if unplanned else c.steps, initial=step, desc="train", dynamic_ncols=True,
               disable=not world.main)
    if ending is not None:
        ending.callback(bar.close)
    model.train()
    started = time.time() - elapsed
    plan.resume(step)
    share = world.share(c.batch_size)
    interruption = interruption or Interruption()

    def weights() -> dict:
        return (ema if ema is not None else model.net).state_dict()

    def save_last() -> None:
        state = {"model": model.net.state_dict(), "optimizer": optimizer.state_dict(), "step": step,
                 "best": best, "elapsed": time.time() - started, "noise_rng": noise_gen.get_state(),
                 "torch_rng": torch.get_rng_state(), "plan": plan.state_dict()}
        if ema is not None:
            state["ema"] = ema.state_dict()
        save_checkpoint(out, "last", model, weights(), state)

    def time_validation() -> float:
        if not (world.main and val_demos):
            return 0.0
        evaluated = copy.deepcopy(model)
        evaluated.net.load_state_dict(weights())
        began = time.time()
        validate(evaluated, val_demos, c.val_samples, seed=c.seed, points=c.val_points)
        return time.time() - began

    def planned(message: str) -> None:
        """The plan's steps into the configuration, config.json and the bar."""
        c.steps, c.val_every, bar.total = plan.steps, plan.val_every, plan.steps
        if world.main:
            cfg.save(config, out / "config.json")
            print(message, file=sys.stderr)

    interrupted = False
    while step < c.steps:
        plan.start_step(step)
        batch = {k: v.to(device) for k, v in next(batches).items()}
        lr = plan.lr_at(step)
        for group in optimizer.param_groups:
            group["lr"] = lr
        # every rank draws the timesteps and noise of the whole global batch and keeps its own rows
        t = model.diffusion.sample_timesteps(c.batch_size, device, noise_gen)[share]
        noise = torch.randn((c.batch_size, *batch["target"].shape[1:]), generator=noise_gen, device=device)[share]
        losses = loss_fn(batch, t, noise)
        if not torch.isfinite(losses["loss"].detach()):
            bar.close()
            raise UsageError(f"--out {out}: the training loss is {float(losses['loss'].detach()):g} at step {step + 1}; "
                             f"expected a finite loss (lower --train.lr, or check the demos); "
                             f"the checkpoints there are from before it")
        optimizer.zero_grad(set_to_none=True)
        losses["loss"].backward()
        if c.grad_clip > 0:
            torch.nn.utils.clip_grad_norm_(model.parameters(), c.grad_clip)
        optimizer.step()
        if ema is not None:
            decay = ema_decay(step, c.ema)
            with torch.no_grad():
                for e, p in zip(ema.parameters(), model.net.parameters()):
                    e.lerp_(p, 1.0 - decay)
        step += 1
        bar.update(1)

        out_of_time = c.time_limit > 0 and time.time() - started > 60 * c.time_limit
        values, (out_of_time, interrupted) = mean_losses(world, losses, out_of_time, interruption.requested)
        record = {"step": step, **values, "lr": lr}
        if plan.timing(step) and c.minutes == 0:
            hours = plan.hours_left(step)
            if world.main and hours > LONG_RUN_HOURS:
                print(f"note: {c.steps} steps at this machine's rate take about {hours:.0f} hours; "
                      f"--train.minutes M plans a run that ends after M minutes", file=sys.stderr)
        elif plan.timing(step):
            record["plan"] = plan.make(step, started, time_validation, agree(world, device))
            planned(f"planned {plan.steps} steps for {c.minutes:g} minutes ({plan.step_seconds:.3f} s per step, "
                    f"{plan.val_seconds:.1f} s per validation)")
        validating = step % c.val_every == 0 or step == c.steps or out_of_time
        if validating:
            val_started = time.time()
            if world.main:
                if val_demos:
                    evaluated = copy.deepcopy(model)
                    evaluated.net.load_state_dict(weights())
                    record.update(validate(evaluated, val_demos, c.val_samples, seed=c.seed, points=c.val_points))
                    if record["val_rmse"] < best:
                        best = record["val_rmse"]
                        save_checkpoint(out, "best", model, weights(), None)
                if c.keep_every and step % c.keep_every == 0:
                    (out / "steps").mkdir(exist_ok=True)
                    save_checkpoint(out / "steps", str(step), model, weights(), None)
                shown = {"loss": f"{record['loss']:.4f}"}
                if "val_rmse" in record:
                    shown["val"] = f"{record['val_rmse']:.3f}"
                bar.set_postfix(shown)
            distributed.barrier(world)
            replan = None if out_of_time else plan.retime(step, started, val_started, agree(world, device))
            if replan is not None:
                record["replan"] = replan
                planned(f"re-planned {plan.steps} steps for {c.minutes:g} minutes ({plan.step_seconds:.3f} s per "
                        f"step since the last timing)")
            if world.main:  # after the re-plan, so that a run resumed from here keeps it
                save_last()
        if world.main:
            record["seconds"] = round(time.time() - started, 2)
            log.write(record)
        if interrupted and world.main and not validating:
            save_last()
        if out_of_time or interrupted:
            break
    bar.close()
    stop_workers(batches)
    if log is not None:
        log.close()
    if interrupted and step < c.steps:
        if world.main:
            print(f"interrupted at step {step} of {c.steps}: saved {out / 'last'}; the same command resumes there",
                  file=sys.stderr)
        raise KeyboardInterrupt
    if world.main:
        write_summary(out, config)
        minutes = (time.time() - started) / 60
        saved = f"best validation RMSE {best:.3f} in {out / 'best'}" if math.isfinite(best) else f"weights in {out / 'last'}"
        print(f"trained {step} steps in {minutes:.1f} min; {saved}", file=sys.stderr)
    return 0


def write_summary(out: Path, config: cfg.Config) -> None:
    """OUT/summary.json: the log's plan, every validation and the last step, what the validations were on, and
    where and when (with the command, when run as `tax3d train`)."""
    records = read_log(out / "log.jsonl")
    kept_records = [r for r in records if "plan" in r or "val_rmse" in r]
    if records and (not kept_records or kept_records[-1] is not records[-1]):
        kept_records.append(records[-1])
    # version 2: the records of version 1 with the run, what it validated on, the machine and the date
    write_json(out / "summary.json", kept.stamp("train-log", 2, {
        **provenance.made("tax3d.train"),
        "run": str(out), "variant": config.model.variant, "val": list(config.data.val),
        "val_demos": config.train.val_demos, "val_samples": config.train.val_samples, "steps": config.train.steps,
        "source": f"{out / 'log.jsonl'}: the plan, every validation and the last step", "records": kept_records}),
        indent=1)


def agree(world: distributed.World, device: torch.device):
    """The plan's numbers every rank takes: their mean over the ranks, rounded."""
    def mean(values: tuple) -> tuple:
        if not world.distributed:
            return values
        means = distributed.mean(world, torch.tensor([float(v) for v in values], device=device))
        return tuple(int(round(float(v))) for v in means)
    return mean


if __name__ == "__main__":
    import tyro

    sys.exit(run(tyro.cli(Args)))
