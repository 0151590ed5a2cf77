"""A checkpoint's model and the policy that executes it: the one place that tells TAX3D from the DP3 baseline."""

from __future__ import annotations

from tax3d.baselines.dp3 import DP3, DP3Policy, is_dp3_checkpoint
from tax3d.devices import pick_device
from tax3d.model.tax3d import Tax3D
from tax3d.policies.goal import GoalPolicy


def load_model(checkpoint, device: str = "cpu") -> Tax3D | DP3:
    """A TAX3D checkpoint, or a DP3 baseline one (its config.json says "kind": "dp3"), on `device`."""
    model = (DP3 if is_dp3_checkpoint(checkpoint) else Tax3D).from_pretrained(checkpoint)
    return model.to(pick_device(device))


def check_sampling(model, steps: int | None, sampler: str | None, prefix: str = "--") -> None:
    """A UsageError where the sampler or its steps do not fit the model (TAX3D's diffusion variants sample; DP3 and
    the regression variants RD/RP take no such options)."""
    if isinstance(model, Tax3D) and model.spec.diffusion:
        model.sampling(steps, sampler, prefix)


def policy_for(predictor, samples: int = 1, steps: int | None = None, seed: int = 0, replan_every: int = 0,
               trajectory: bool = False, offset=(0.0, 0.0, 0.0), sampler: str | None = None,
               max_points: int | None = None, observe=None):
    """The policy that executes `predictor`: DP3 its own action windows (no goal), anything that predicts goals
    (TAX3D, a FixedGoal) the goal policy of appendix A.3 with these settings."""
    if isinstance(predictor, DP3):
        return DP3Policy(predictor, seed)
    return GoalPolicy(predictor, samples, steps, seed, replan_every, trajectory=trajectory, offset=offset,
                      sampler=sampler, max_points=max_points, observe=observe)
