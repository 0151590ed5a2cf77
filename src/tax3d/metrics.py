"""Goal-prediction metrics (paper App. C; REFERENCE.md, Evaluation) and the trivial mean-goal predictor.

Every function takes numpy arrays or torch tensors of world-frame points and returns the same kind.
"""

from __future__ import annotations

import numpy as np
import torch


def _lib(x):
    return torch if isinstance(x, torch.Tensor) else np


def rmse(pred, goal):
    """sqrt of the mean over points of the squared L2 error: (..., N, 3), (..., N, 3) -> (...)."""
    lib = _lib(pred)
    return lib.sqrt(((pred - goal) ** 2).sum(-1).mean(-1))


def min_of_samples_rmse(samples, goal):
    """Per-demo minimum RMSE over samples: samples (..., K, N, 3), goal (..., N, 3) -> (...).

    Averaged over demos this is the validation metric, and with K = 20 the coverage RMSE of a unimodal task."""
    errors = rmse(samples, goal[..., None, :, :])
    return errors.min(-1).values if isinstance(errors, torch.Tensor) else errors.min(-1)


def coverage_rmse(samples, goals):
    """Coverage RMSE of one cloth: for each ground-truth goal, the min RMSE over the samples; averaged.

    samples (K, N, 3) predicted for this cloth; goals (G, N, 3) its demonstrations' goals (G = 1 unimodal)."""
    errors = rmse(samples[None], goals[:, None])  # (G, K)
    best = errors.min(1).values if isinstance(errors, torch.Tensor) else errors.min(1)
    return best.mean()


def precision_rmse(samples, goals):
    """Precision RMSE of one cloth: for each sample, the min RMSE over the cloth's ground-truth goals; averaged."""
    errors = rmse(samples[None], goals[:, None])  # (G, K)
    best = errors.min(0).values if isinstance(errors, torch.Tensor) else errors.min(0)
    return best.mean()


class MeanGoalBaseline:
    """Predicts the training demos' mean goal in the anchor frame, placed at the new anchor's mean.

    The official cloth is the same in every demo and its vertices correspond, so the mean is taken point by point."""

    def __init__(self, goals_in_anchor_frame: np.ndarray):
        self.goal = np.asarray(goals_in_anchor_frame, dtype=np.float64)  # (N, 3)

    @classmethod
    def fit(cls, demos) -> "MeanGoalBaseline":
        """demos: dicts with action_pc, anchor_pc and flow, all with the same number of action points."""
        goals = [d["action_pc"] + d["flow"] - d["anchor_pc"].mean(0) for d in demos]
        if len({g.shape for g in goals}) != 1:
            raise ValueError("the mean-goal baseline needs the same number of action points in every demo")
        return cls(np.mean(goals, axis=0))

    def predict(self, action_points, anchor_points) -> np.ndarray:
        if len(action_points) != len(self.goal):
            raise ValueError(f"{len(action_points)} action points; this baseline was fitted on {len(self.goal)}")
        return self.goal + np.asarray(anchor_points, dtype=np.float64).mean(0)
