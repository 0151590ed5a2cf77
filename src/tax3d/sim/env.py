"""The HangProcCloth scene in PyBullet: reset with cloth parameters and an anchor pose, PD-driven grippers, release."""

from __future__ import annotations

import contextlib
import itertools
import os
import tempfile
import weakref
from dataclasses import dataclass

import numpy as np
import pybullet

from tax3d.sim.anchor import add_floor, goal_position, load_anchor
from tax3d.sim.camera import anchor_cloud
from tax3d.sim.cloth import ClothMesh, build_cloth
from tax3d.sim.success import cloth_success

# docs/reference.md, "HangProcCloth scene" and "Units and frames".
TIMESTEP = 1.0 / 500.0
SIM_STEPS_PER_ACTION = 8
RELEASE_SIM_STEPS = 500
CLOTH_POSITION = (0.0, 5.0, 8.0)
CLOTH_EULER = (-np.pi / 2, 0.0, 3 * np.pi / 2)
CLOTH_SCALE = 3.0
SOFT_BODY = dict(
    mass=1.0,
    collisionMargin=0.003,
    useMassSpring=1,
    useBendingSprings=1,
    useNeoHookean=0,
    springElasticStiffness=50.0,
    springDampingStiffness=0.01,
    springDampingAllDirections=1,
    springBendingStiffness=1.0,
    frictionCoeff=0.1,
    useFaceContact=1,
    useSelfCollision=1,
)
GRIPPER_MASS, GRIPPER_RADIUS = 0.1, 0.05
KP = KD = 50.0  # PD gains (appendix A.3)
FORCE_CLIP = 5.0  # per-axis clip, not a norm (appendix A.3, footnote)
EXPLODED_EXTENT = 60.0  # a vertex this far from the origin means the simulation blew up


_LOADS = itertools.count(1)


def _release(client: int) -> None:
    try:
        pybullet.disconnect(client)
    except pybullet.error:
        pass


@contextlib.contextmanager
def mesh_file(stem: str):
    """A path for one mesh file PyBullet loads once, in a temporary folder removed as soon as the load is done (a
    pool worker ends without running finalizers, so nothing may wait for exit). The name is new for every load in
    the process: PyBullet caches meshes by file name."""
    with tempfile.TemporaryDirectory(prefix=f"tax3d-{os.getpid()}-") as folder:
        yield os.path.join(folder, f"{stem}_{next(_LOADS)}.obj")


class SimulationExploded(RuntimeError):
    """NaN or far-flung cloth vertices: the episode is failed and never saved."""


@dataclass
class SceneState:
    cloth: np.ndarray  # (V, 3) cloth mesh vertices, world frame
    grippers: np.ndarray  # (2, 3) gripper positions
    velocities: np.ndarray  # (2, 3) gripper linear velocities


class HangClothEnv:
    """One PyBullet world per instance (DIRECT mode)."""

    scene = "cloth"

    def __init__(self, floor: bool = True):
        self.floor = floor
        self.client = pybullet.connect(pybullet.DIRECT)
        self.mesh: ClothMesh | None = None
        self.cloth_id = -1
        self.gripper_ids: list[int] = []
        self.anchor_ids: tuple[int, int] = (-1, -1)
        self.rot_z, self.trans = 0.0, np.zeros(3)
        self._finalizer = weakref.finalize(self, _release, self.client)

    def close(self) -> None:
        self._finalizer()
        self.client = -1

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    # ----------------------------------------------------------------- reset
    def reset(self, cloth_params: dict, rot_z: float, trans) -> SceneState:
        c = self._new_world(rot_z, trans)
        self.mesh = build_cloth(cloth_params)
        self.anchor_ids = load_anchor(c, self.rot_z, self.trans)
        with mesh_file("cloth") as obj:
            with open(obj, "w") as f:
                f.write(self.mesh.obj_text())
            self.cloth_id = pybullet.loadSoftBody(
                obj,
                basePosition=CLOTH_POSITION,
                baseOrientation=pybullet.getQuaternionFromEuler(CLOTH_EULER),
                scale=CLOTH_SCALE,
                physicsClientId=c,
                **SOFT_BODY,
            )
        vertices = self.cloth_vertices()
        if len(vertices) != self.mesh.num_vertices:
            raise RuntimeError(f"soft body has {len(vertices)} vertices, mesh file {self.mesh.num_vertices}")
        return self._finish_reset(vertices)

    def _new_world(self, rot_z: float, trans) -> int:
        """An empty deformable world with gravity, the time step and the floor; remembers the anchor pose."""
        c = self.client
        self.rot_z, self.trans = float(rot_z), np.asarray(trans, dtype=np.float64)
        pybullet.resetSimulation(pybullet.RESET_USE_DEFORMABLE_WORLD, physicsClientId=c)
        pybullet.setGravity(0, 0, -9.8, physicsClientId=c)
        pybullet.setTimeStep(TIMESTEP, physicsClientId=c)
        if self.floor:
            add_floor(c)
        return c

    def _finish_reset(self, vertices: np.ndarray) -> SceneState:
        """After the soft body is loaded: SDF voxel size, look, and a gripper tied to each grip vertex."""
        c = self.client
        pybullet.setPhysicsEngineParameter(sparseSdfVoxelSize=0.25, physicsClientId=c)
        pybullet.changeVisualShape(
            self.cloth_id, -1, rgbaColor=[0.95, 0.95, 1.0, 1], flags=pybullet.VISUAL_SHAPE_DOUBLE_SIDED,
            physicsClientId=c,
        )
        self.gripper_ids = []
        for v in self.mesh.grip_vertices():
            shape = pybullet.createCollisionShape(pybullet.GEOM_SPHERE, radius=GRIPPER_RADIUS, physicsClientId=c)
            look = pybullet.createVisualShape(
                pybullet.GEOM_SPHERE, radius=GRIPPER_RADIUS, rgbaColor=[1, 0, 1, 1], physicsClientId=c
            )
            body = pybullet.createMultiBody(
                GRIPPER_MASS, shape, look, basePosition=vertices[v].tolist(), useMaximalCoordinates=True,
                physicsClientId=c,
            )  # fmt: skip
            pybullet.createSoftBodyAnchor(self.cloth_id, int(v), body, -1, physicsClientId=c)
            self.gripper_ids.append(body)
        return self.state()

    # ----------------------------------------------------------------- observations
    def cloth_vertices(self) -> np.ndarray:
        _, verts = pybullet.getMeshData(
            self.cloth_id, -1, flags=pybullet.MESH_DATA_SIMULATION_MESH, physicsClientId=self.client
        )
        return np.asarray(verts, dtype=np.float64)

    def gripper_state(self) -> tuple[np.ndarray, np.ndarray]:
        c = self.client
        pos = np.array([pybullet.getBasePositionAndOrientation(g, physicsClientId=c)[0] for g in self.gripper_ids])
        vel = np.array([pybullet.getBaseVelocity(g, physicsClientId=c)[0] for g in self.gripper_ids])
        return pos, vel

    def state(self) -> SceneState:
        cloth = self.cloth_vertices()
        if not np.all(np.isfinite(cloth)) or np.abs(cloth).max() > EXPLODED_EXTENT:
            raise SimulationExploded("cloth vertices are NaN or far-flung")
        pos, vel = self.gripper_state()
        return SceneState(cloth, pos, vel)

    def anchor_points(self) -> np.ndarray:
        return anchor_cloud(self.rot_z, self.trans, with_floor=self.floor)

    def goal(self) -> np.ndarray:
        return goal_position(self.rot_z, self.trans)

    def aim_vertices(self, part: int) -> np.ndarray:
        """The vertices the expert brings to the goal: the loop of hole `part`."""
        return self.mesh.loops[part]

    def judge(self, pre: np.ndarray, post: np.ndarray) -> dict:
        """The success check (appendix A.4.2) on the cloth before and after release."""
        return cloth_success(pre, post, self.mesh.loops, self.goal())

    # ----------------------------------------------------------------- control
    def step(self, targets: np.ndarray) -> None:
        """One environment step: SIM_STEPS_PER_ACTION simulation steps of PD force control towards targets (2, 3)."""
        c = self.client
        for _ in range(SIM_STEPS_PER_ACTION):
            for g, target in zip(self.gripper_ids, targets):
                pos, _ = pybullet.getBasePositionAndOrientation(g, physicsClientId=c)
                vel, _ = pybullet.getBaseVelocity(g, physicsClientId=c)
                force = KP * (np.asarray(target) - pos) + KD * (0.0 - np.asarray(vel))
                force = np.clip(force, -FORCE_CLIP, FORCE_CLIP)
                pybullet.applyExternalForce(g, -1, force.tolist(), pos, pybullet.WORLD_FRAME, physicsClientId=c)
            pybullet.stepSimulation(physicsClientId=c)

    def release(self, steps: int = RELEASE_SIM_STEPS) -> None:
        """The release phase: the grippers stay tied to the cloth but no force is applied.

        docs/reference.md, HangProcCloth scene.
        """
        for _ in range(steps):
            pybullet.stepSimulation(physicsClientId=self.client)
