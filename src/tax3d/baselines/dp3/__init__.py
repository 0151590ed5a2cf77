"""The DP3 baseline (3D Diffusion Policy, Ze et al. 2024) as the TAX3D authors ran it: docs/dp3.md. Its policy in a
rollout is tax3d.policies.dp3."""

from tax3d.baselines.dp3.config import DP3Config, is_dp3_checkpoint
from tax3d.baselines.dp3.model import DP3

__all__ = ["DP3", "DP3Config", "is_dp3_checkpoint"]
