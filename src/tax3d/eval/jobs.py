"""The episodes of an evaluation: one EvalJob each, planned from `tax3d eval`'s arguments."""

from __future__ import annotations

import dataclasses
import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from tax3d.data.format import demo_index, list_demos, load_demo
from tax3d.errors import UsageError
from tax3d.policies.fixed import MeanGoalBaseline
from tax3d.policies.goal import Sampling
from tax3d.sim.tasks import episode_params, get_split, get_task

# The official data's `val_ood` folder holds out-of-distribution poses; its `val` folder is evaluated as `val`.
SPLIT_FOLDERS = {"train": ("train",), "val": ("val",), "unseen": ("unseen",), "ood": ("ood", "val_ood")}


@dataclass
class EvalJob:
    split: str
    name: str
    cloth_params: dict
    rot_z: float
    trans: list
    floor: bool
    checkpoint: str
    true_goal: np.ndarray | None = None
    sampling: Sampling = field(default_factory=Sampling)  # the seed is the episode's own
    denoising: bool = False
    task: str = "hangproccloth-simple"
    offset: tuple | None = None  # gripper-target offset; None: the task's
    device: str = "cpu"
    goal: str = "model"  # model, demo or mean (`tax3d eval --goal`)
    mean_goal: MeanGoalBaseline | None = None  # with goal "mean": fitted on the training demos
    observe: str = "mesh"  # `tax3d eval --observe`
    camera: object = None  # observe "camera": the CameraSpec
    observation: np.ndarray | None = None  # observe "camera" with a demo: its action_pc, the camera's cloud
    cloth_index: int = 0  # which cloth of the split: seeds the camera noise as `tax3d generate` does

    def policy_goal(self):
        """What the policy executes: the checkpoint, the demo's own goal or the mean goal."""
        return {"model": self.checkpoint, "demo": self.true_goal, "mean": self.mean_goal}[self.goal]


def cloth_key(job: EvalJob) -> str:
    """Episodes with the same cloth and anchor pose share a key: their goals are one cloth's modes (appendix C)."""
    return json.dumps([job.split, job.cloth_params, round(job.rot_z, 9), [round(t, 9) for t in job.trans]])


def split_folder(data: Path | None, split: str) -> Path | None:
    if data is None:
        return None
    for name in SPLIT_FOLDERS[split]:
        if (data / name).is_dir():
            return data / name
    return None


def plan_jobs(args, sampling: Sampling) -> list[EvalJob]:
    """The jobs of `tax3d eval` ARGS (its Args), each episode predicting with SAMPLING from its own seed."""
    task = get_task(args.task)
    split_names = [s.strip() for s in args.splits.split(",") if s.strip()]
    canonical = [get_split(name).name for name in split_names]
    twice = next((name for i, name in enumerate(canonical) if name in canonical[:i]), None)
    if twice is not None:
        raise UsageError(f"--splits {args.splits!r}: {twice} is named twice; expected each split once (its episodes "
                         f"would be scored twice)")
    if args.data is not None:
        if not args.data.is_dir():
            raise UsageError(f"--data {args.data}: no such folder; expected one demo folder per split inside it")
        wanted = [name for split_name in split_names for name in SPLIT_FOLDERS[get_split(split_name).name]]
        if next(args.data.glob("demo_*.npz"), None) is not None:
            raise UsageError(f"--data {args.data}: holds demo files itself; expected the folder above it, with a "
                             f"folder per split ({', '.join(dict.fromkeys(wanted))})")
        if all(split_folder(args.data, get_split(name).name) is None for name in split_names):
            raise UsageError(f"--data {args.data}: has none of the folders {', '.join(dict.fromkeys(wanted))}; "
                             f"expected a demo folder per split inside it")
    mean_goal = _fixed_goal(args, split_names) if args.goal != "model" else None
    common = dict(checkpoint=str(args.checkpoint), task=task.name, device=args.device,
                  offset=None if args.policy_offset is None else tuple(float(v) for v in args.policy_offset),
                  goal=args.goal, mean_goal=mean_goal, observe=args.observe, camera=args.camera)

    def seeded(index: int) -> Sampling:
        return dataclasses.replace(sampling, seed=sampling.seed + index)

    jobs = []
    for split_name in split_names:
        split = get_split(split_name)
        folder = split_folder(args.data, split.name)
        if folder is not None:
            for path in demos_from(folder, args.first_index, args.episodes):
                demo = load_demo(path)
                trans = demo["trans"]
                floor = bool(demo["anchor_pc"][:, 2].min() >= trans[2] - 0.05)
                jobs.append(EvalJob(split.name, path.stem, demo["deform_params"], float(demo["rot"][2]),
                                    trans.tolist(), floor, true_goal=demo["action_pc"] + demo["flow"],
                                    sampling=seeded(demo_index(path)),
                                    cloth_index=demo_index(path) // task.demos_per_cloth,
                                    observation=demo["action_pc"] if args.observe == "camera" else None, **common))
        else:
            num = task.sizes[split.name] if args.episodes is None else args.episodes
            for i in range(args.first_index, args.first_index + num):
                params = episode_params(task, split, i // task.demos_per_cloth)
                jobs.append(EvalJob(split.name, f"episode_{i}", params.cloth_params, params.rot_z,
                                    params.trans.tolist(), True, sampling=seeded(i),
                                    cloth_index=i // task.demos_per_cloth, **common))
    if not jobs:
        raise UsageError(f"--splits {args.splits!r}: no episodes to evaluate")
    jobs[0].denoising = True
    return jobs


def demos_from(folder: Path, first: int, episodes: int | None) -> list[Path]:
    """The demo files of a split folder with index FIRST to FIRST + EPISODES - 1 (default: every index from FIRST
    on); the summary counts the episodes found."""
    end = None if episodes is None else first + episodes
    paths = [p for p in list_demos(folder) if demo_index(p) >= first and (end is None or demo_index(p) < end)]
    if not paths:
        raise UsageError(f"--data {folder}: no demo files from demo_{first}.npz on; expected demos at or after "
                         f"--first-index {first}")
    return paths


def _fixed_goal(args, split_names: list[str]) -> MeanGoalBaseline | None:
    """--goal demo or mean: check that every split has its demos; for mean, fit the training set's mean goal."""
    if args.data is None:
        raise UsageError(f"--goal {args.goal}: needs --data, the folder of the demos whose goals it executes")
    missing = [name for name in split_names if split_folder(args.data, get_split(name).name) is None]
    if missing:
        raise UsageError(f"--goal {args.goal}: --data {args.data} has no demo folder for {', '.join(missing)}; "
                         f"expected one per split, the goals come from the demos")
    if args.goal == "demo":
        return None
    train = split_folder(args.data, "train")
    if train is None:
        raise UsageError(f"--goal mean: --data {args.data} has no train folder to take the mean goal from")
    try:
        return MeanGoalBaseline.fit([load_demo(path) for path in list_demos(train)])
    except ValueError as err:
        raise UsageError(f"--data {train}: {err}") from None
