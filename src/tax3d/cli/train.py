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
import math
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Annotated, Optional

import torch
import tyro

from tax3d import config as cfg
from tax3d import devices
from tax3d import kept
from tax3d import provenance
from tax3d.atomic import write_json
from tax3d.checkpoint import read_log
from tax3d.data.dataset import DemoDataset, demo_files
from tax3d.data.format import data_task
from tax3d.errors import UsageError
from tax3d.options import OutputFolder
from tax3d.training import distributed, rerun, runlock
from tax3d.training.interrupt import Interruption
from tax3d.training.loop import fit
from tax3d.training.tax3d import Tax3DLearner, pick_precision
from tax3d.training.validation import load_val_demos


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


# --- configuration ---------------------------------------------------------------------------------------------


def resolve_config(args: Args, out: Path, last: Path | None) -> cfg.Config:
    """The command's configuration; resuming, the run's (its planned steps kept), which the command's must equal
    (tax3d.training.rerun), but for the options that change only how the run computes."""
    overrides = dict(model=args.model, diffusion=args.diffusion, data=args.data, train=args.train)
    return rerun.resolve(cfg, cfg.preset(default_preset(args.preset)), overrides, out, last, args.resume)


def config_of_command(argv: list[str]) -> cfg.Config:
    """The configuration a fresh run of `tax3d train ARGV` starts from (before a --train.minutes plan)."""
    return resolve_config(tyro.cli(Args, args=argv, prog="tax3d train"), Path("."), None)


def default_preset(name: str | None) -> str:
    return devices.machine_preset(name, "cpu-fast")


def pick_device(name: str) -> torch.device:
    return devices.pick_device(name, "--train.device")


def run(args: Args) -> int:
    """Train in OUT, holding its lock (tax3d.training.runlock) until every process of the run has ended."""
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
            learner = Tax3DLearner(config, out, dataset, val_demos, device, dtype, world)
            step = fit(learner, out, last, world, interruption, ending)
    except BaseException:
        distributed.stop(world)
        raise
    distributed.stop(world, finished=True)
    if world.main:
        write_summary(out, config)
        best = learner.best
        saved = f"best validation RMSE {best:.3f} in {out / 'best'}" if math.isfinite(best) else f"weights in {out / 'last'}"
        minutes = read_log(out / "log.jsonl")[-1]["seconds"] / 60
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
        **provenance.made("tax3d.cli.train"),
        "run": str(out), "variant": config.model.variant, "val": list(config.data.val),
        "val_demos": config.train.val_demos, "val_samples": config.train.val_samples, "steps": config.train.steps,
        "source": f"{out / 'log.jsonl'}: the plan, every validation and the last step", "records": kept_records}),
        indent=1)
