"""Goals that no network predicts, behind the `predict` interface of `Tax3D`: the policy's ceiling and floor."""

from __future__ import annotations

import numpy as np


class FixedGoal:
    """A demo's own goal (an array), or the training set's mean goal (a `tax3d.metrics.MeanGoalBaseline`)."""

    def __init__(self, goal):
        self.goal = goal

    def predict(self, action_points, anchor_points, num_samples=1, steps=None, sampler=None, seed=None,
                return_trajectory=False, max_points=None):
        goal = self.goal.predict(action_points, anchor_points) if hasattr(self.goal, "predict") else self.goal
        goals = np.repeat(np.asarray(goal, dtype=np.float64)[None], num_samples, axis=0)
        return (goals, goals[None]) if return_trajectory else goals
