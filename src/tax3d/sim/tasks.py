"""Tasks (HangProcCloth, HangBag) and splits: deformable and anchor-pose samplers with a seed for every index."""

from __future__ import annotations

import zlib
from dataclasses import dataclass

import numpy as np

from tax3d.errors import UsageError
from tax3d.sim.bag import FIXED_BAG, POLICY_OFFSET
from tax3d.sim.cloth import SIMPLE_CLOTH, sample_cloth_params


@dataclass(frozen=True)
class TaskSpec:
    name: str
    num_holes: int
    fixed_cloth: dict | None  # None: a random cloth per demonstration (or per pair, multimodal)
    sizes: dict  # default number of demonstrations per split (appendix A.5.2)
    demos_per_cloth: int = 1  # multimodal: one demonstration per hole of the same cloth and anchor pose
    scene: str = "cloth"  # "cloth": HangProcCloth's cloth and hanger; "bag": HangBag's bag and hook
    # Added to the predicted grip-vertex positions to give the evaluation policy's gripper targets (docs/reference.md,
    # "Evaluation"; world frame).
    policy_offset: tuple = (0.0, 0.0, 0.0)


@dataclass(frozen=True)
class SplitSpec:
    name: str
    seed: int  # docs/reference.md, HangProcCloth scene: train 0, val 10 (our unseen), val_ood 20 (our ood)
    ood: bool


TASKS = {
    t.name: t
    for t in (
        TaskSpec("hangproccloth-simple", 1, SIMPLE_CLOTH, {"train": 16, "val": 40, "unseen": 40, "ood": 40}),
        TaskSpec("hangproccloth-unimodal", 1, None, {"train": 64, "val": 40, "unseen": 40, "ood": 40}),
        TaskSpec("hangproccloth-multimodal", 2, None, {"train": 64, "val": 40, "unseen": 40, "ood": 40}, demos_per_cloth=2),
        # One fixed bag (appendix A.5.2); the expert aims at handle 0, the one facing the hook.
        TaskSpec("hangbag", 1, FIXED_BAG, {"train": 16, "val": 40, "unseen": 40, "ood": 40}, scene="bag",
                 policy_offset=POLICY_OFFSET),
    )
}
# `val` is the split every choice is made on (weights kept, recipe, sample selection, policy settings): anchor
# poses and cloths from the training distribution under a seed of its own, so no val episode is a test episode.
SPLITS = {s.name: s for s in (SplitSpec("train", 0, False), SplitSpec("val", 30, False), SplitSpec("unseen", 10, False),
                              SplitSpec("ood", 20, True))}
# The paper's table is scored on unseen and ood demos from this index on (demo_100 ...): episodes that no choice
# made before the table (training validation, earlier pages) has touched.
TEST_FIRST_INDEX = 100


def get_task(name: str) -> TaskSpec:
    if name not in TASKS:
        raise UsageError(f"--task: unknown task {name!r}; expected one of {', '.join(TASKS)}")
    return TASKS[name]


def get_split(name: str) -> SplitSpec:
    if name not in SPLITS:
        raise UsageError(f"--split: unknown split {name!r}; expected one of {', '.join(SPLITS)}")
    return SPLITS[name]


def sample_anchor_pose(rng: np.random.Generator, ood: bool) -> tuple[float, np.ndarray]:
    """Appendix A.5.1 (one table for HangProcCloth and HangBag): rotation U(-pi/3, pi/3) about z; the x-translation
    takes the rotation's sign."""
    rot_z = float(rng.uniform(-np.pi / 3, np.pi / 3))
    sign = 1.0 if rot_z >= 0 else -1.0
    if ood:
        x, y, z = rng.uniform(5, 10) * sign, rng.uniform(-10, 0), rng.uniform(1, 5)
    else:
        x, y, z = rng.uniform(0, 5) * sign, rng.uniform(-10, 0), 0.0
    return rot_z, np.array([x, y, z], dtype=np.float64)


@dataclass(frozen=True)
class EpisodeParams:
    task: str
    split: str
    cloth_index: int  # which cloth of the split (multimodal: two demonstrations share one)
    attempt: int  # resampled when the expert fails, so every index still yields a demonstration
    cloth_params: dict
    rot_z: float
    trans: np.ndarray


def episode_params(task: TaskSpec, split: SplitSpec, cloth_index: int, attempt: int = 0) -> EpisodeParams:
    """Reproducible parameters for one cloth of a split: a seed sequence over (split seed, task, cloth, attempt)."""
    task_key = zlib.crc32(task.name.encode())
    rng = np.random.default_rng(np.random.SeedSequence([split.seed, task_key, cloth_index, attempt]))
    cloth = dict(task.fixed_cloth) if task.fixed_cloth is not None else sample_cloth_params(rng, task.num_holes)
    rot_z, trans = sample_anchor_pose(rng, split.ood)
    return EpisodeParams(task.name, split.name, cloth_index, attempt, cloth, rot_z, trans)
