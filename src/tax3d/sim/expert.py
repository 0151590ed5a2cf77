"""The scripted pseudo-expert of appendix A.3 (targets from the loop centroid, with a per-step correction)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from tax3d.sim import anchor, hook
from tax3d.sim.anchor import pose_points, rotation_z
from tax3d.sim.success import loop_centroid


@dataclass(frozen=True)
class ExpertRule:
    goal_local: tuple  # the goal in the anchor's frame
    offset: tuple  # added to the targets in the anchor's frame
    approach: tuple = (0.0, 0.0, 0.0)  # a waypoint: added too, in the anchor's frame, during the first steps
    approach_steps: int = 0


# HangProcCloth: docs/reference.md, "Pseudo-expert and episode". HangBag (docs/hangbag.md): the same rule with the
# hook as the goal, the handle's strap as the aimed vertices, an offset that leaves the handle between the pole and
# the hook's pin, and a first stretch of 100 steps 2 units out along the hook's arm and 0.5 higher, so that the
# handle comes in along the arm at large anchor rotations instead of catching it from the side.
EXPERT_RULES = {
    "cloth": ExpertRule(tuple(anchor.GOAL_LOCAL), (0.0, -1.5, 0.0)),
    "bag": ExpertRule(tuple(hook.GOAL_LOCAL), (0.0, -1.0, 0.5), approach=(0.0, 2.0, 0.5), approach_steps=100),
}


class PseudoExpert:
    """Fixed gripper targets from the initial state, plus a unit-clipped pull of the aimed centroid to the goal.

    `aim` is the vertex set whose centroid goes to the goal: a hole's loop, or a bag handle's strap.
    """

    def __init__(self, grippers: np.ndarray, cloth: np.ndarray, aim: np.ndarray, rot_z: float, trans,
                 scene: str = "cloth"):
        rule = EXPERT_RULES[scene]
        goal_local = np.asarray(rule.goal_local)
        self.loop = np.asarray(aim)
        shift = goal_local - loop_centroid(cloth, self.loop) + np.asarray(rule.offset)
        self.base = pose_points(np.asarray(grippers) + shift, rot_z, trans)
        self.goal = pose_points(goal_local[None], rot_z, trans)[0]
        self.approach = rotation_z(rot_z) @ np.asarray(rule.approach)
        self.approach_steps, self.step = rule.approach_steps, 0

    def targets(self, cloth: np.ndarray) -> np.ndarray:
        correction = self.goal - loop_centroid(cloth, self.loop)
        norm = np.linalg.norm(correction)
        if norm > 1.0:
            correction = correction / norm
        self.step += 1
        return self.base + correction + (self.approach if self.step <= self.approach_steps else 0.0)
