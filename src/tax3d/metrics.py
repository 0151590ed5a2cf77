"""Goal-prediction metrics (paper App. C; docs/reference.md, Evaluation) and the trivial mean-goal predictor.

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


def success_interval(successes: int, episodes: int, confidence: float = 0.95) -> tuple[float, float]:
    """The Wilson score interval of a success rate (scipy's), e.g. 35 of 40 -> (0.74, 0.95)."""
    from scipy.stats import binomtest

    ci = binomtest(int(successes), int(episodes)).proportion_ci(confidence_level=confidence, method="wilson")
    return float(ci.low), float(ci.high)


def rate(successes: int, episodes: int) -> str:
    """A success rate as its fraction allows: the fewest decimals, two at least, that give it exactly (3 of 40:
    0.075, 33 of 40: 0.825), to three places where none does."""
    for places in (2, 3, 4):
        if successes * 10**places % episodes == 0:
            return f"{successes / episodes:.{places}f}"
    return f"{successes / episodes:.3f}"


def split_rate(split: dict) -> str:
    """`rate` of a summary's split (success_rate and episodes); two decimals where it gives no episodes."""
    if not split.get("episodes"):
        return f"{split['success_rate']:.2f}"
    return rate(round(split["success_rate"] * split["episodes"]), split["episodes"])


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


def medoid(samples) -> int:
    """Index of the goal sample (K, N, 3) with the least summed RMSE to the other samples: the consensus goal."""
    return int(rmse(samples[:, None], samples[None]).sum(1).argmin())


def grip_error(samples, goal, grip) -> float:
    """Mean distance of the goal samples (..., N, 3) from `goal` (N, 3) at the grasped rows `grip`, where the policy
    sends the grippers."""
    grip = list(grip)
    return float(np.linalg.norm(samples[..., grip, :] - goal[grip], axis=-1).mean())


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


def medoid_rmse(goals: list[np.ndarray], errors: np.ndarray) -> float:
    """Mean over demos of the RMSE of each demo's medoid sample (the one with the least summed RMSE to the others)."""
    return float(np.mean([e[medoid(g)] for g, e in zip(goals, errors)]))
