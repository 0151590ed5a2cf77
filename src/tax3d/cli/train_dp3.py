"""`tax3d train-dp3`: fit the DP3 baseline on demos with trajectories (`tax3d generate --trajectories`).

    tax3d train-dp3 --preset cpu --data.train data/demos/train --out runs/dp3 [--train.steps 2000]

The options are the dotted config fields of `tax3d train` (`--model.*`, `--diffusion.*`, `--data.*`, `--train.*`).

OUT gets config.json, log.jsonl (one line per step) and last/: a checkpoint directory (config.json and
model.safetensors, the EMA weights, for `tax3d eval --checkpoint OUT/last`) plus training_state.pt to resume from.
A run whose OUT already holds last/ continues from it, if it is the same run (tax3d.training.rerun: the same options and
demos; --fresh starts afresh); the run holds OUT's lock (tax3d.training.runlock) while it writes there. Each
step's batch, rotations, diffusion steps and noise come from a generator seeded by (seed, step), so a resumed run
sees what an uninterrupted one would. The loop is `tax3d train`'s (tax3d.training.loop), with each save of last/
in the place of a validation: a `--train.minutes` run's first steps fix train.steps, and every save times it again;
Ctrl-C or SIGTERM saves last/ at the end of the step.
"""

from __future__ import annotations

import contextlib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Annotated, Literal, Optional

import torch

from tax3d.baselines.dp3 import config as cfg
from tax3d.baselines.dp3.dataset import TrajectoryDataset
from tax3d.data.dataset import demo_files
from tax3d.data.format import data_task
from tax3d.devices import machine_preset, pick_device
from tax3d.errors import UsageError
from tax3d.options import OutputFolder
from tax3d.training import rerun, runlock
from tax3d.training.distributed import World
from tax3d.training.dp3 import DP3Learner
from tax3d.training.interrupt import Interruption
from tax3d.training.loop import fit


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


def resolve_config(args: Args, out: Path, last: Path | None) -> cfg.DP3Config:
    """The preset with the given options applied; resuming, the run's saved config (its planned steps kept), which
    the command's must equal (tax3d.training.rerun)."""
    overrides = dict(model=args.model, diffusion=args.diffusion, data=args.data, train=args.train)
    return rerun.resolve(cfg, cfg.preset(default_preset(args.preset)), overrides, out, last, args.resume)


def default_preset(name: str | None) -> str:
    return machine_preset(name, "cpu")


def run(args: Args) -> int:
    with runlock.hold(Path(args.out)):
        return run_locked(args)


def run_locked(args: Args) -> int:
    out = Path(args.out)
    last = rerun.checkpoint_to_resume(out, args.resume, args.fresh)
    config = resolve_config(args, out, last)
    if config.train.threads > 0:
        torch.set_num_threads(config.train.threads)
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
    learner = DP3Learner(config, out, dataset, device)
    if args.fresh:
        rerun.clear_run(out)
    if last is None or not (out / rerun.DIGEST_NAME).is_file():
        rerun.keep_digests(out, digests)
    with contextlib.ExitStack() as ending, Interruption() as interruption:
        fit(learner, out, last, World(), interruption, ending)
    return 0
