"""The rigid anchor of HangBag, built from primitives: a hook sticking out of a tall pole, and its point cloud."""

from __future__ import annotations

import functools

import numpy as np
import pybullet

from tax3d.sim.anchor import fixed_cylinders, pose_points
from tax3d.sim.camera import render_canonical

# docs/reference.md, "HangBag": body poses, world units.
POLE_POSITION, POLE_EULER = (0.0, 0.0, 5.0), (np.pi / 2, 0.0, 0.0)
HOOK_POSITION, HOOK_EULER = (0.0, 1.28, 9.0), (0.0, 0.0, np.pi / 2)
# The goal is the hook's origin, in the anchor's frame (DEDO's HangBag goal_pos).
GOAL_LOCAL = np.array(HOOK_POSITION)
# (radius, length, centre xyz, Euler xyz) of each cylinder in its body's frame.
# The pole's axis is its frame's y, which POLE_EULER turns upright: a rod of radius 0.25 from z = 0 to 10 on a disc.
POLE_PARTS = (
    (0.25, 10.0, (0.0, 0.0, 0.0), (-np.pi / 2, 0.0, 0.0)),
    (1.0, 0.2, (0.0, -4.9, 0.0), (-np.pi / 2, 0.0, 0.0)),
)
# The hook's frame x points away from the pole (HOOK_EULER turns it to world +y, towards the bag). DEDO's hook
# (hook_small.urdf at scale 10): an arm of radius 0.1 along the line through (-1.1, 0, 0) rising 18 degrees (72 from
# vertical), so 0.357 above the hook's origin at x = 0 and ending at x = 0.089; an upright pin of length 0.5 centred
# at (0, 0, 0.5). Here the arm runs from the pole's axis (x = -1.28) to that tip through the same point above the
# origin, and the pin has radius 0.05. The arm dips 10 degrees towards the tip instead of rising: measured here, on a
# rising or level arm a hung handle slid back against the pole, its centroid 1.2-1.9 from the goal (the success
# threshold is 1.4); on this one it stays near the goal (~0.9).
ARM_TILT = np.deg2rad(-10.0)
_ARM_X = (-1.28, 0.089)
_ARM_CENTRE = (float(np.mean(_ARM_X)), 0.0, float(0.357 + np.mean(_ARM_X) * np.tan(ARM_TILT)))
HOOK_PARTS = (
    (0.1, float(np.diff(_ARM_X)[0] / np.cos(ARM_TILT)), _ARM_CENTRE, (0.0, float(np.pi / 2 - ARM_TILT), 0.0)),
    (0.05, 0.5, (0.0, 0.0, 0.5), (0.0, 0.0, 0.0)),
)


def goal_position(rot_z: float, trans) -> np.ndarray:
    return pose_points(GOAL_LOCAL[None], rot_z, trans)[0]


def _body(client: int, parts, position, euler, rot_z: float, trans) -> int:
    # PyBullet's Euler angles compose as Rz(yaw) Ry(pitch) Rx(roll): the anchor's z-rotation adds to the yaw.
    return fixed_cylinders(
        client,
        radii=[r for r, *_ in parts],
        lengths=[length for _, length, *_ in parts],
        centres=[list(centre) for _, _, centre, _ in parts],
        orientations=[pybullet.getQuaternionFromEuler(e) for *_, e in parts],
        position=pose_points(np.asarray(position)[None], rot_z, trans)[0].tolist(),
        orientation=pybullet.getQuaternionFromEuler([euler[0], euler[1], euler[2] + rot_z]),
    )


def load_hook(client: int, rot_z: float = 0.0, trans=(0.0, 0.0, 0.0)) -> tuple[int, int]:
    """Create the hook and the pole, fixed, under the anchor pose p -> Rz(rot_z) p + trans; returns their ids."""
    hook = _body(client, HOOK_PARTS, HOOK_POSITION, HOOK_EULER, rot_z, trans)
    pole = _body(client, POLE_PARTS, POLE_POSITION, POLE_EULER, rot_z, trans)
    return hook, pole


@functools.lru_cache(maxsize=4)
def canonical_hook_cloud(with_floor: bool) -> np.ndarray:
    """The hook and pole rendered once at rot = 0, trans = 0 with the HangProcCloth camera, like the hanger."""
    return render_canonical(load_hook, with_floor)


def hook_cloud(rot_z: float, trans, with_floor: bool = True) -> np.ndarray:
    """The anchor cloud under a random pose: the canonical render moved by p -> Rz p + trans."""
    return pose_points(canonical_hook_cloud(with_floor), rot_z, trans)


def cylinders(rot_z: float = 0.0, trans=(0.0, 0.0, 0.0)) -> list[tuple[np.ndarray, np.ndarray, float, float]]:
    """(centre, unit axis, radius, half length) in the world of every cylinder of the hook and the pole."""
    out = []
    for parts, position, euler in ((HOOK_PARTS, HOOK_POSITION, HOOK_EULER), (POLE_PARTS, POLE_POSITION, POLE_EULER)):
        body = _matrix([euler[0], euler[1], euler[2] + rot_z])
        origin = pose_points(np.asarray(position)[None], rot_z, trans)[0]
        for radius, length, centre, part_euler in parts:
            axis = body @ _matrix(part_euler)[:, 2]  # a PyBullet cylinder's axis is its frame's z
            out.append((origin + body @ np.asarray(centre), axis, float(radius), float(length) / 2))
    return out


def penetration(points: np.ndarray, rot_z: float = 0.0, trans=(0.0, 0.0, 0.0)) -> np.ndarray:
    """Per point, how deep it lies inside the hook or the pole (0 outside): the distance to the nearest face."""
    points = np.asarray(points, dtype=np.float64)
    depth = np.zeros(len(points))
    for centre, axis, radius, half in cylinders(rot_z, trans):
        rel = points - centre
        along = rel @ axis
        across = np.linalg.norm(rel - along[:, None] * axis, axis=1)
        depth = np.maximum(depth, np.minimum(radius - across, half - np.abs(along)))
    return depth


def _matrix(euler) -> np.ndarray:
    return np.array(pybullet.getMatrixFromQuaternion(pybullet.getQuaternionFromEuler(list(euler)))).reshape(3, 3)
