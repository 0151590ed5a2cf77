"""The rigid anchor of HangProcCloth, built from primitives: the hanger and the tall rod it stands on."""

from __future__ import annotations

import numpy as np
import pybullet

# docs/reference.md, "HangProcCloth scene": sizes before the global scale of 10.
SCALE = 10.0
HANGER_POSITION = np.array([0.0, 0.0, 8.0])
# (radius, length, centre xyz, rotation about y in degrees) of each hanger cylinder.
HANGER_PARTS = (
    (0.01, 0.05, (0.0, 0.0, 0.055), 0.0),  # vertical top piece
    (0.01, 0.15, (-0.07, 0.0, 0.005), 72.0),  # left arm, rising towards the middle
    (0.01, 0.15, (0.07, 0.0, 0.005), 108.0),  # right arm
)
ROD_PARTS = (
    (0.1, 0.05, (0.0, 0.0, 0.0), 0.0),  # base disc
    (0.03, 0.8, (0.0, 0.0, 0.4), 0.0),  # the rod itself
)
# Goal location in the anchor's frame (docs/reference.md, HangProcCloth scene): the centre of the hanger.
GOAL_LOCAL = np.array([0.0, 0.0, 8.2])


def rotation_z(angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def pose_points(points: np.ndarray, rot_z: float, trans: np.ndarray) -> np.ndarray:
    """p -> Rz(rot_z) p + trans: the anchor's random pose, about the world origin."""
    return np.asarray(points) @ rotation_z(rot_z).T + np.asarray(trans)


def goal_position(rot_z: float, trans: np.ndarray) -> np.ndarray:
    return pose_points(GOAL_LOCAL[None], rot_z, trans)[0]


def fixed_cylinders(client: int, radii, lengths, centres, orientations, position, orientation) -> int:
    """A fixed body of cylinders (radius, length, centre and quaternion in the body's frame) at a world pose."""
    kw = dict(radii=radii, lengths=lengths, physicsClientId=client)
    collision = pybullet.createCollisionShapeArray(
        [pybullet.GEOM_CYLINDER] * len(radii),
        collisionFramePositions=centres,
        collisionFrameOrientations=orientations,
        **kw,
    )
    visual = pybullet.createVisualShapeArray(
        [pybullet.GEOM_CYLINDER] * len(radii),
        visualFramePositions=centres,
        visualFrameOrientations=orientations,
        rgbaColors=[[0.55, 0.4, 0.25, 1.0]] * len(radii),
        **kw,
    )
    body = pybullet.createMultiBody(
        baseMass=0.0,
        baseCollisionShapeIndex=collision,
        baseVisualShapeIndex=visual,
        basePosition=list(position),
        baseOrientation=orientation,
        physicsClientId=client,
    )
    # docs/reference.md, "HangProcCloth scene": rigid objects have friction 1 and restitution 0.
    pybullet.changeDynamics(
        body, -1, lateralFriction=1.0, spinningFriction=1.0, rollingFriction=1.0, restitution=0.0,
        physicsClientId=client,
    )  # fmt: skip
    return body


def load_anchor(client: int, rot_z: float = 0.0, trans=(0.0, 0.0, 0.0)) -> tuple[int, int]:
    """Create the hanger and the rod, fixed, under the anchor pose; returns their body ids."""
    ids = []
    for parts, base in ((HANGER_PARTS, HANGER_POSITION), (ROD_PARTS, np.zeros(3))):
        ids.append(fixed_cylinders(
            client,
            radii=[r * SCALE for r, _, _, _ in parts],
            lengths=[length * SCALE for _, length, _, _ in parts],
            centres=[[c * SCALE for c in centre] for _, _, centre, _ in parts],
            orientations=[pybullet.getQuaternionFromEuler([0.0, np.deg2rad(deg), 0.0]) for *_, deg in parts],
            position=pose_points(base[None], rot_z, trans)[0].tolist(),
            orientation=pybullet.getQuaternionFromEuler([0.0, 0.0, rot_z]),
        ))  # fmt: skip
    return ids[0], ids[1]


def add_floor(client: int) -> int:
    """The floor: a wide slab whose top face is the plane z = 0 (a box renders in the CPU renderer, a plane warns)."""
    half = [100.0, 100.0, 0.5]
    shape = pybullet.createCollisionShape(pybullet.GEOM_BOX, halfExtents=half, physicsClientId=client)
    look = pybullet.createVisualShape(
        pybullet.GEOM_BOX, halfExtents=half, rgbaColor=[0.85, 0.85, 0.8, 1], physicsClientId=client
    )
    return pybullet.createMultiBody(0, shape, look, basePosition=[0, 0, -0.5], physicsClientId=client)
