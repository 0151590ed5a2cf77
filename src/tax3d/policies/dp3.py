"""The DP3 baseline in a rollout: `run_episode(env, ..., make_policy=DP3Policy.from_pretrained(dir))`.

Called as policy(env, state) after reset, then policy.targets(cloth) at every environment step. It keeps the last
n_obs_steps observations (the first one repeated at t = 0), predicts an action window every n_action_steps steps
and executes its first n_action_steps actions, absolute gripper targets (2, 3).
"""

from __future__ import annotations

import time
from collections import deque

import numpy as np
import torch

from tax3d.baselines.dp3.model import DP3
from tax3d.geometry import farthest_point_sample


class DP3Policy:
    """A DP3 model executing its own action windows; no goal prediction (RMSE does not apply)."""

    def __init__(self, model: DP3, seed: int = 0):
        self.model, self.seed = model.eval(), seed
        self.predict_seconds, self.predictions = 0.0, 0
        self.first_prediction = self.first_cloud = self.grip = None  # GoalPolicy's: DP3 predicts no goal cloud
        self.denoising = None

    @classmethod
    def from_pretrained(cls, directory, seed: int = 0, map_location="cpu") -> "DP3Policy":
        return cls(DP3.from_pretrained(directory, map_location), seed)

    def __call__(self, env, state):
        data, m = self.model.config.data, self.model.config.model
        generator = torch.Generator().manual_seed(self.seed)
        # One cloth vertex subset for the episode (the cloth keeps its correspondences), like the demos' recorder.
        cloth = torch.as_tensor(state.cloth)
        self.cloth_idx = farthest_point_sample(cloth, min(data.num_action_points, len(cloth)), generator).numpy()
        anchor = torch.as_tensor(env.anchor_points())
        self.anchor = anchor[farthest_point_sample(anchor, data.num_anchor_points, generator)].numpy()
        self.env, self.generator = env, generator
        self.history: deque = deque(maxlen=m.n_obs_steps)
        self.plan: list[np.ndarray] = []
        self.predictions, self.predict_seconds = 0, 0.0
        return self

    def _observe(self, cloth: np.ndarray) -> None:
        pos, vel = self.env.gripper_state()
        points = np.concatenate([np.asarray(cloth)[self.cloth_idx], self.anchor])  # (n + m, 3)
        self.history.append((points, np.concatenate([np.ravel(pos), np.ravel(vel)])))
        while len(self.history) < self.history.maxlen:  # t = 0: the first observation stands for the earlier ones
            self.history.appendleft(self.history[0])

    def _predict(self) -> None:
        start = time.perf_counter()
        points = torch.as_tensor(np.stack([p for p, _ in self.history])[None], dtype=torch.float32)  # (1, To, N, 3)
        state = torch.as_tensor(np.stack([s for _, s in self.history])[None], dtype=torch.float32)  # (1, To, 12)
        actions = self.model.predict_action(points, state, self.generator)[0].cpu().double().numpy()  # (H, 6)
        self.plan = [a.reshape(2, 3) for a in actions[: self.model.config.model.n_action_steps]]
        self.predictions += 1
        self.predict_seconds += time.perf_counter() - start

    def targets(self, cloth: np.ndarray) -> np.ndarray:
        self._observe(cloth)
        if not self.plan:
            self._predict()
        return self.plan.pop(0)
