"""The scripted pseudo-expert of appendix A.3 (targets from the loop centroid, with a per-step correction)."""

from __future__ import annotations

import numpy as np

from tax3d.sim.anchor import GOAL_LOCAL, pose_points
from tax3d.sim.success import loop_centroid

# REFERENCE.md, "Pseudo-expert": the extra offset added to the targets before the anchor pose.
TARGET_OFFSET = np.array([0.0, -1.5, 0.0])


class PseudoExpert:
    """Fixed gripper targets from the initial state, plus a unit-clipped pull of the loop centroid to the goal."""

    def __init__(self, grippers: np.ndarray, cloth: np.ndarray, loop: np.ndarray, rot_z: float, trans):
        self.loop = np.asarray(loop)
        shift = GOAL_LOCAL - loop_centroid(cloth, self.loop) + TARGET_OFFSET
        self.base = pose_points(np.asarray(grippers) + shift, rot_z, trans)
        self.goal = pose_points(GOAL_LOCAL[None], rot_z, trans)[0]

    def targets(self, cloth: np.ndarray) -> np.ndarray:
        correction = self.goal - loop_centroid(cloth, self.loop)
        norm = np.linalg.norm(correction)
        if norm > 1.0:
            correction = correction / norm
        return self.base + correction
