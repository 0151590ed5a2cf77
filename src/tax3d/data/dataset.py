"""Training samples: point sampling, object-specific frames, augmentation and the target of each variant.

Frames and targets follow the paper (Section 3.1, "Object-Specific Frames") and docs/reference.md, "Model":
anchor frame = anchor points minus the anchor mean, action frame = action points minus the action mean;
the goal is expressed in the anchor frame. A sample's frame origins are kept so that `to_world` maps a
model output (a cross-displacement or goal points, in the variant's frame) back to world-frame goal points.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

import numpy as np
import torch
from torch.utils.data import Dataset

from tax3d.data.format import DemoError, grip_vertices, list_demos, load_demo
from tax3d.errors import UsageError
from tax3d.frames import frame_inputs, to_world
from tax3d.geometry import farthest_point_sample, random_angle, rotate_z
from tax3d.variants import VARIANTS, VariantSpec, variant_spec


def make_target(goal: torch.Tensor, frames: dict, spec: VariantSpec) -> torch.Tensor:
    """The variant's target for world goal points (..., N, 3): (..., N, 3), or (..., N + M, 3) for SD/SP.

    CD: goal in the anchor frame minus action in the action frame; CP: goal in the anchor frame
    (docs/reference.md, Model). SD/SP append the anchor's target: zero displacement, or the anchor points.
    """
    goal_in_frame = goal - frames["anchor_mean"][..., None, :]
    if spec.target == "displacement":
        target = goal_in_frame - frames["action"]
        anchor_target = torch.zeros_like(frames["anchor"])
    else:
        target = goal_in_frame
        anchor_target = frames["anchor"]
    if spec.scene:
        target = torch.cat([target, anchor_target], dim=-2)
    return target


def _sample_indices(points: torch.Tensor, k: int | None, generator: torch.Generator | None) -> torch.Tensor:
    if k is None:
        return torch.arange(points.shape[0])
    return farthest_point_sample(points, k, start=generator)


def occluded(points: torch.Tensor, generator: torch.Generator | None, rows: torch.Tensor) -> torch.Tensor:
    """`rows` of `points` (K, 3) with a part hidden, the hidden rows replaced by repeats of seen ones (the sample
    keeps its size): with even odds, a ball about a random point (radius U(0.1, 0.3) of the cloud's diameter) or the
    side of a random plane through one (the authors' release cuts both kinds out of real clouds). A cut that would
    hide more than half of the points hides none."""
    def uniform() -> float:
        return float(torch.rand((), generator=generator, dtype=torch.float64))

    centre = points[int(torch.randint(len(points), (), generator=generator))]
    if uniform() < 0.5:
        diameter = float(torch.cdist(points, points).max())
        hidden = (points - centre).norm(dim=-1) < (0.1 + 0.2 * uniform()) * diameter
    else:
        normal = torch.randn(3, generator=generator, dtype=torch.float64)
        hidden = (points - centre) @ (normal / normal.norm()).to(points.dtype) > 0
    seen = torch.nonzero(~hidden).flatten()
    if len(seen) * 2 < len(points):
        return rows
    refill = seen[torch.randint(len(seen), (int(hidden.sum()),), generator=generator)]
    rows = rows.clone()
    rows[hidden] = rows[refill]
    return rows


def make_sample(
    action,
    anchor,
    goal,
    spec: VariantSpec | str,
    generator: torch.Generator | None = None,
    num_action_points: int | None = 512,
    num_anchor_points: int | None = 512,
    rotate: bool = False,
    indices: tuple[torch.Tensor, torch.Tensor] | None = None,
    rotate_scene: bool = False,
    occlusion: float = 0.0,
) -> dict:
    """One training sample from world-frame action (N, 3), anchor (M, 3) and goal (N, 3) points.

    FPS picks num_action_points and num_anchor_points (None: all points, in order). With `rotate`, the
    anchor and the goal turn about z by U(0, 2 pi) and the action does not (docs/reference.md, Training): the
    result is a new scene, and `goal` is that scene's world-frame goal. With `rotate_scene`, first the whole scene
    (action, anchor and goal) turns about z by U(0, 2 pi), the authors' release's `random_flat_upright` transform: a
    scene the policy could meet, where anchor rotation makes one whose goal no demonstration shows. With chance
    `occlusion`, the sampled action cloud loses a ball- or plane-shaped part (`occluded`), as a camera's view of it
    might. `indices` (action rows, anchor rows) given replace the sampling. Returns float32 tensors (plus the int64
    action_idx); see `DemoDataset` for the keys.
    """
    spec = variant_spec(spec)
    action, anchor, goal = (torch.as_tensor(x, dtype=torch.float64) for x in (action, anchor, goal))
    if indices is None:
        indices = (_sample_indices(action, num_action_points, generator),
                   _sample_indices(anchor, num_anchor_points, generator))
    action_idx = indices[0]
    if occlusion > 0 and float(torch.rand((), generator=generator)) < occlusion:
        action_idx = occluded(action[action_idx], generator, action_idx)
    anchor = anchor[indices[1]]
    action, goal = action[action_idx], goal[action_idx]

    # The pivot is the anchor mean (the rotation happens in the anchor frame), except for -W, which has no
    # object frame: there the scene turns about the world origin.
    pivot = anchor.mean(0) if (spec.object_centric or spec.scene) else anchor.new_zeros(3)
    if rotate_scene:
        turn = random_angle(generator)
        action, anchor, goal = (rotate_z(x - pivot, turn) + pivot for x in (action, anchor, goal))
    angle = random_angle(generator) if rotate else 0.0
    if rotate:
        anchor = rotate_z(anchor - pivot, angle) + pivot
        goal = rotate_z(goal - pivot, angle) + pivot

    frames = frame_inputs(action, anchor, spec)
    sample = {
        **frames,
        "target": make_target(goal, frames, spec),
        "goal": goal,
        "angle": torch.tensor(angle, dtype=torch.float64),
        "pivot": pivot,
    }
    sample = {key: value.to(torch.float32) for key, value in sample.items()}
    sample["action_idx"] = action_idx.to(torch.int64)
    return sample


def demo_files(sources) -> list[Path]:
    """The demo files of one or more folders or files, folders expanded in index order."""
    if isinstance(sources, (str, os.PathLike)):
        sources = [sources]
    files: list[Path] = []
    for source in sources:
        source = Path(source)
        if source.suffix == ".npz" and not source.is_dir():
            files.append(source)
        else:
            files.extend(list_demos(source))
    if not files:
        raise UsageError("no demonstration folders or files given")
    return files


def split_demos(paths, val_fraction: float = 0.1, seed: int = 0) -> tuple[list[Path], list[Path]]:
    """(train, val) demo files carved at random from one or more folders or files; each part non-empty."""
    files = demo_files(paths)
    if not 0.0 < val_fraction < 1.0:
        raise UsageError(f"val_fraction is {val_fraction}; expected a value between 0 and 1")
    if len(files) < 2:
        raise UsageError(f"{files[0].parent}: {len(files)} demonstration(s); a validation split needs at least 2")
    n_val = min(max(1, round(len(files) * val_fraction)), len(files) - 1)
    order = np.random.default_rng(seed).permutation(len(files))
    val = set(order[:n_val].tolist())
    return [f for i, f in enumerate(files) if i not in val], [f for i, f in enumerate(files) if i in val]


class DemoDataset(Dataset):
    """Samples for one variant from the demos of one or more folders (or demo files), cached in memory.

    Each item is a dict of tensors (Na = num_action_points, Nb = num_anchor_points):
      action (Na, 3), anchor (Nb, 3): inputs in the variant's frames (`frame_inputs`)
      action_mean, anchor_mean (3,): world positions of those frames' origins
      target (Na, 3), or (Na + Nb, 3) for SD/SP: the variant's target
      goal (Na, 3): the world-frame goal of the (possibly rotated) scene; to_world(target, item) returns it
      angle (): the augmentation's z-rotation; pivot (3,): the world point it turned about
      action_idx (Na,) int64: rows of the demo's action cloud; demo_index () int64: position in `files`
      point_weight (Na,), or (Na + Nb,) for SD/SP, only with grip_weight != 1: the loss weight of each target
        row, grip_weight at the demo's grasped vertices (its `anchors`), 1 elsewhere; 1 everywhere for a demo
        without `anchors` (said once on stderr)
    NAC variants get the same items as CD/CP: to_world needs the action points, the model ignores them.
    Item i of epoch e uses demo i % len(files) and a generator seeded by (seed, e, i); call set_epoch(e)
    before each epoch (with DataLoader workers, before the loader's iterator is made).
    With `subsets` > 0 the point sampling is done once: each demo gets that many farthest-point subsets (each from
    its own random first point, seeded by (seed, demo, subset)) and an item picks one of them at random; without
    rotation the whole sample of each subset is made once and kept.
    """

    def __init__(
        self,
        sources,
        variant: str | VariantSpec = "cd",
        *,
        train: bool = True,
        rotate: bool | None = None,
        rotate_scene: bool = False,
        occlusion: float = 0.0,
        num_action_points: int | None = 512,
        num_anchor_points: int | None = 512,
        train_size: int | None = None,
        seed: int = 0,
        subsets: int = 0,
        grip_weight: float = 1.0,
    ):
        self.spec = variant_spec(variant)
        self.files = demo_files(sources)
        if train_size is not None and train_size < 1:
            raise UsageError(f"train_size is {train_size}; expected a positive number of samples per epoch")
        self.rotate = train if rotate is None else rotate
        self.rotate_scene = bool(rotate_scene)
        self.occlusion = float(occlusion)
        self.num_action_points = num_action_points
        self.num_anchor_points = num_anchor_points
        self.train_size = train_size
        if not grip_weight > 0:
            raise UsageError(f"grip_weight is {grip_weight}; expected a positive loss weight")
        self.grip_weight = float(grip_weight)
        self.seed = int(seed)
        self.epoch = 0
        self.demos, self.grip = [], []
        for path in self.files:
            demo = load_demo(path)
            self.grip.append(torch.tensor(grip_vertices(demo), dtype=torch.int64))
            self.demos.append(tuple(torch.from_numpy(np.asarray(x, dtype=np.float64)) for x in (
                demo["action_pc"], demo["anchor_pc"], demo["action_pc"] + demo["flow"])))
        unweighted = [path for path, grip in zip(self.files, self.grip) if not len(grip)]
        if self.grip_weight != 1.0 and unweighted:
            print(f"note: {len(unweighted)} of {len(self.files)} demos (such as {unweighted[0]}) name no grasped "
                  f"vertices (no anchors key): their points are weighted 1, grip_weight {self.grip_weight:g} applies "
                  f"to the others", file=sys.stderr)
        if subsets < 0:
            raise UsageError(f"subsets is {subsets}; expected 0 (sample points afresh) or a positive number")
        self.subsets = [self._subsets(d, subsets) for d in range(len(self.demos))] if subsets else None
        self.cached = None
        if self.subsets is not None and not (self.rotate or self.rotate_scene or self.occlusion):
            self.cached = [[self._sample(d, idx, None) for idx in demo] for d, demo in enumerate(self.subsets)]

    def _subsets(self, demo_index: int, count: int) -> list[tuple[torch.Tensor, torch.Tensor]]:
        action, anchor, _ = self.demos[demo_index]
        out = []
        for j in range(count):
            seed = np.random.SeedSequence([self.seed, demo_index, j, 1]).generate_state(1)[0]
            generator = torch.Generator().manual_seed(int(seed))
            out.append((_sample_indices(action, self.num_action_points, generator),
                        _sample_indices(anchor, self.num_anchor_points, generator)))
        return out

    def _sample(self, demo_index: int, indices, generator: torch.Generator | None) -> dict:
        action, anchor, goal = self.demos[demo_index]
        sample = make_sample(
            action, anchor, goal, self.spec, generator,
            self.num_action_points, self.num_anchor_points, self.rotate, indices, self.rotate_scene,
            self.occlusion,
        )
        sample["demo_index"] = torch.tensor(demo_index, dtype=torch.int64)
        if self.grip_weight != 1.0:
            weight = torch.ones(sample["target"].shape[0], dtype=torch.float32)
            weight[:len(sample["action_idx"])][torch.isin(sample["action_idx"], self.grip[demo_index])] = self.grip_weight
            sample["point_weight"] = weight
        return sample

    def set_epoch(self, epoch: int) -> None:
        self.epoch = int(epoch)

    def __len__(self) -> int:
        # train_size samples an epoch (App. B.2), but never fewer than the demos: sample i is of demo i mod D
        return max(self.train_size or 0, len(self.demos))

    def generator(self, index: int) -> torch.Generator:
        seed = np.random.SeedSequence([self.seed, self.epoch, index]).generate_state(1)[0]
        return torch.Generator().manual_seed(int(seed))

    def __getitem__(self, index: int) -> dict:
        if not 0 <= int(index) < len(self):
            raise IndexError(f"index {index} out of range for {len(self)} samples")
        index = int(index)
        demo_index = index % len(self.demos)
        generator = self.generator(index)
        if self.subsets is None:
            return self._sample(demo_index, None, generator)
        j = int(torch.randint(len(self.subsets[demo_index]), (), generator=generator))
        if self.cached is not None:
            return dict(self.cached[demo_index][j])
        return self._sample(demo_index, self.subsets[demo_index][j], generator)


__all__ = [
    "VARIANTS", "VariantSpec", "variant_spec", "frame_inputs", "make_target", "to_world", "make_sample",
    "demo_files", "split_demos", "DemoDataset", "DemoError",
]
