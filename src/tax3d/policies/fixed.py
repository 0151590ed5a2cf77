"""Goals that no network predicts, behind the `predict` interface of `Tax3D`: the policy's ceiling and floor."""

from __future__ import annotations

import numpy as np


class FixedGoal:
    """A demo's own goal (an array), or the training set's mean goal (a `MeanGoalBaseline`)."""

    def __init__(self, goal):
        self.goal = goal

    def predict(self, action_points, anchor_points, num_samples=1, steps=None, sampler=None, seed=None,
                return_trajectory=False, max_points=None):
        goal = self.goal.predict(action_points, anchor_points) if isinstance(self.goal, MeanGoalBaseline) \
            else self.goal
        goals = np.repeat(np.asarray(goal, dtype=np.float64)[None], num_samples, axis=0)
        return (goals, goals[None]) if return_trajectory else goals


class MeanGoalBaseline:
    """Predicts the training demos' mean goal in the anchor frame, placed at the new anchor's mean.

    One fixed deformable (HangProcCloth-simple, HangBag): its vertices correspond from demo to demo, so the mean is
    taken point by point. Random cloths (unimodal, multimodal): each point of the new cloth takes, in every training
    demo, the goal of the nearest point of that demo's initial cloud, and those goals are averaged; for one fixed
    cloth this is the same point-by-point mean."""

    def __init__(self, goals_in_anchor_frame: np.ndarray, starts: list | None = None, goals: list | None = None):
        self.goal = np.asarray(goals_in_anchor_frame, dtype=np.float64)  # (N, 3); empty for random cloths
        self.starts, self.goals = starts, goals  # per training demo: initial action cloud, goal in anchor frame

    @classmethod
    def fit(cls, demos) -> "MeanGoalBaseline":
        """demos: dicts with action_pc, anchor_pc and flow."""
        demos = list(demos)
        if not demos:
            raise ValueError("the mean-goal baseline needs at least one training demo")
        goals = [d["action_pc"] + d["flow"] - d["anchor_pc"].mean(0) for d in demos]
        first = demos[0]["action_pc"]
        if all(d["action_pc"].shape == first.shape and np.abs(d["action_pc"] - first).max() < 1e-3 for d in demos):
            return cls(np.mean(goals, axis=0))
        return cls(np.zeros((0, 3)), [np.asarray(d["action_pc"], dtype=np.float64) for d in demos], goals)

    def predict(self, action_points, anchor_points) -> np.ndarray:
        center = np.asarray(anchor_points, dtype=np.float64).mean(0)
        if self.starts is None:
            if len(action_points) != len(self.goal):
                raise ValueError(f"{len(action_points)} action points; this baseline was fitted on {len(self.goal)}")
            return self.goal + center
        action = np.asarray(action_points, dtype=np.float64)
        nearest = [goal[((action[:, None] - start[None]) ** 2).sum(-1).argmin(1)]
                   for start, goal in zip(self.starts, self.goals)]
        return np.mean(nearest, axis=0) + center
