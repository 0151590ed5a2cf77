"""Goal-prediction metrics (paper App. C; docs/reference.md, Evaluation).

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


def medoid_rmse(goals: list[np.ndarray], errors: np.ndarray) -> float:
    """Mean over demos of the RMSE of each demo's medoid sample (the one with the least summed RMSE to the others)."""
    return float(np.mean([e[medoid(g)] for g, e in zip(goals, errors)]))
