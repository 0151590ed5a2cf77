"""DP3 training samples from demos written with `tax3d generate --trajectories` (their traj_* arrays).

Sample t of an episode of T steps: the observations of steps t - To + 1 .. t and the expert's actions of steps
t .. t + H - 1, indices clipped to [0, T - 1] (the first observation and the last action repeated, as Diffusion
Policy pads its sequences), so every step of every episode is a sample.
"""

from __future__ import annotations

import numpy as np
import torch
from torch.utils.data import Dataset

from tax3d.data.dataset import demo_files
from tax3d.data.format import load_demo
from tax3d.errors import UsageError
from tax3d.geometry import rotate_z

TRAJECTORY_KEYS = ("traj_gripper_pos", "traj_gripper_vel", "traj_targets", "traj_action_pc", "traj_anchor_pc")


def episode_arrays(demo: dict, where: str, num_action_points: int, num_anchor_points: int) -> dict:
    """cloth (T, n, 3), anchor (m, 3), state (T, 12) and action (T, 6) of one demo, as float32 tensors."""
    missing = [k for k in TRAJECTORY_KEYS if k not in demo]
    if missing:
        raise UsageError(f"{where}: no {', '.join(missing)} arrays; expected a demo written by "
                         f"`tax3d generate --trajectories`")
    pos, vel, targets = demo["traj_gripper_pos"], demo["traj_gripper_vel"], demo["traj_targets"]
    cloth, anchor = demo["traj_action_pc"], demo["traj_anchor_pc"]
    steps = len(pos)
    for key in ("traj_gripper_pos", "traj_gripper_vel", "traj_targets"):
        if steps == 0 or demo[key].shape != (steps, 2, 3):
            raise UsageError(f"{where}: {key} has shape {demo[key].shape}; expected (T, 2, 3) with T > 0 steps")
    if cloth.ndim != 3 or cloth.shape[0] != steps or cloth.shape[2] != 3:
        raise UsageError(f"{where}: traj_action_pc has shape {cloth.shape}; expected ({steps}, n, 3)")
    if cloth.shape[1] < num_action_points or anchor.ndim != 2 or len(anchor) < num_anchor_points:
        raise UsageError(f"{where}: {cloth.shape[1]} cloth and {len(anchor)} anchor points stored; the model needs "
                         f"{num_action_points} and {num_anchor_points}")
    # The stored clouds are in farthest-point order, so a prefix is itself a farthest-point sample.
    return {
        "cloth": torch.as_tensor(cloth[:, :num_action_points], dtype=torch.float32),
        "anchor": torch.as_tensor(anchor[:num_anchor_points], dtype=torch.float32),
        "state": torch.as_tensor(np.concatenate([pos.reshape(steps, 6), vel.reshape(steps, 6)], 1),
                                 dtype=torch.float32),
        "action": torch.as_tensor(targets.reshape(steps, 6), dtype=torch.float32),
    }


class TrajectoryDataset(Dataset):
    """Every (episode, step) of the demos: points (To, n + m, 3), state (To, 12), action (H, 6)."""

    def __init__(self, sources, horizon: int = 4, n_obs_steps: int = 2, num_action_points: int = 512,
                 num_anchor_points: int = 512):
        self.horizon, self.n_obs_steps = horizon, n_obs_steps
        self.episodes = [episode_arrays(load_demo(path), str(path), num_action_points, num_anchor_points)
                         for path in demo_files(sources)]
        self.index = [(e, t) for e, ep in enumerate(self.episodes) for t in range(len(ep["state"]))]

    def __len__(self) -> int:
        return len(self.index)

    def __getitem__(self, i: int) -> dict:
        e, t = self.index[i]
        ep = self.episodes[e]
        last = len(ep["state"]) - 1
        obs = torch.arange(t - self.n_obs_steps + 1, t + 1).clamp(0, last)
        act = torch.arange(t, t + self.horizon).clamp(0, last)
        anchor = ep["anchor"].expand(len(obs), -1, -1)
        return {"points": torch.cat([ep["cloth"][obs], anchor], dim=1), "state": ep["state"][obs],
                "action": ep["action"][act]}

    def normalizer_data(self) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """All points (P, 3), states (S, 12) and actions (S, 6) of the episodes, for fitting the normalisers."""
        points = torch.cat([torch.cat([ep["cloth"].reshape(-1, 3), ep["anchor"]]) for ep in self.episodes])
        return (points, torch.cat([ep["state"] for ep in self.episodes]),
                torch.cat([ep["action"] for ep in self.episodes]))


def rotate_batch(batch: dict, angles: torch.Tensor) -> dict:
    """Points, state and actions of each sample rotated about the world z axis by its angle (B,): every 3-vector
    (points, gripper positions, velocities and targets) turns together, so the sample stays consistent."""
    def turn(x: torch.Tensor) -> torch.Tensor:
        flat = x.reshape(x.shape[0], -1, 3)  # (B, K, 3)
        return rotate_z(flat, angles).reshape(x.shape)

    return {key: turn(value) for key, value in batch.items()}
