"""A checkpoint's model and the policy that executes a goal: the one place that tells TAX3D from the DP3 baseline."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import torch

from tax3d.baselines.dp3 import DP3, is_dp3_checkpoint
from tax3d.devices import pick_device
from tax3d.model.tax3d import Tax3D
from tax3d.policies.dp3 import DP3Policy
from tax3d.policies.fixed import FixedGoal, MeanGoalBaseline
from tax3d.policies.goal import GoalPolicy, Sampling

_LOADED: dict = {}  # (checkpoint, device): the model, loaded once a process


def load_model(checkpoint, device: str = "cpu") -> Tax3D | DP3:
    """A TAX3D checkpoint, or a DP3 baseline one (its config.json says "kind": "dp3"), on `device`."""
    model = (DP3 if is_dp3_checkpoint(checkpoint) else Tax3D).from_pretrained(checkpoint)
    return model.to(pick_device(device))


def check_sampling(model, steps: int | None, sampler: str | None, prefix: str = "--") -> None:
    """A UsageError where the sampler or its steps do not fit the model (TAX3D's diffusion variants sample; DP3 and
    the regression variants RD/RP take no such options)."""
    if isinstance(model, Tax3D) and model.spec.diffusion:
        model.sampling(steps, sampler, prefix)


def _model(checkpoint, device: str):
    if (str(checkpoint), device) not in _LOADED:
        torch.set_num_threads(1)  # one thread a worker process, each with its own copy of the model
        _LOADED[str(checkpoint), device] = load_model(checkpoint, device)
    return _LOADED[str(checkpoint), device]


def load_policy(goal, sampling: Sampling = Sampling(), device: str = "cpu", trajectory: bool = False,
                offset=(0.0, 0.0, 0.0), observe=None):
    """The policy that executes `goal`: a checkpoint folder (loaded once a process, on `device`), a model, or a goal
    that no network predicts (a demo's own goal array, a MeanGoalBaseline). DP3 executes its own action windows (no
    goal, sampling.seed alone); anything that predicts goals, the goal policy of appendix A.3 with these settings."""
    if isinstance(goal, (str, Path)):
        goal = _model(goal, device)
    elif isinstance(goal, (np.ndarray, MeanGoalBaseline)):
        goal = FixedGoal(goal)
    if isinstance(goal, DP3):
        return DP3Policy(goal, sampling.seed)
    return GoalPolicy(goal, sampling, trajectory=trajectory, offset=offset, observe=observe)
