"""One episode (HangProcCloth or HangBag): reset, manipulation under a policy, release, success check, demo."""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Callable, Protocol

import numpy as np

from tax3d.sim.env import HangClothEnv, SceneState, SimulationExploded
from tax3d.sim.expert import PseudoExpert

MANIPULATION_STEPS = 300  # environment steps (docs/reference.md, "Pseudo-expert and episode")
TRAJECTORY_POINTS = 512


class Policy(Protocol):
    def targets(self, cloth: np.ndarray) -> np.ndarray: ...


@dataclass
class Episode:
    success: bool
    exploded: bool
    checks: dict
    cloth_params: dict
    rot_z: float
    trans: np.ndarray
    action_pc: np.ndarray | None = None  # initial cloth vertices
    anchor_pc: np.ndarray | None = None
    goal_pc: np.ndarray | None = None  # cloth at the end of manipulation, before release
    released_pc: np.ndarray | None = None  # cloth after the release phase
    grip_vertices: tuple = ()
    gripper_ids: list = field(default_factory=list)
    initial_grippers: np.ndarray | None = None
    trajectory: dict = field(default_factory=dict)
    frames: list = field(default_factory=list)
    seconds: float = 0.0


def expert_policy(hole: int = 0) -> Callable[[HangClothEnv, SceneState], Policy]:
    def make(env: HangClothEnv, state: SceneState) -> Policy:
        return PseudoExpert(state.grippers, state.cloth, env.aim_vertices(hole), env.rot_z, env.trans, env.scene)

    return make


def run_episode(
    env: HangClothEnv,
    cloth_params: dict,  # the deformable's parameters: a cloth's, or a bag's
    rot_z: float,
    trans,
    make_policy: Callable[[HangClothEnv, SceneState], Policy],
    steps: int = MANIPULATION_STEPS,
    trajectory: bool = False,
    frame_every: int = 0,
    render=None,
) -> Episode:
    """Run one episode; an exploded simulation returns a failed Episode rather than raising."""
    start = time.perf_counter()
    episode = Episode(False, False, {}, cloth_params, float(rot_z), np.asarray(trans, dtype=np.float64))
    try:
        state = env.reset(cloth_params, rot_z, trans)
        episode.action_pc = state.cloth.copy()
        episode.anchor_pc = env.anchor_points()
        episode.grip_vertices = env.mesh.grip_vertices()
        episode.gripper_ids = list(env.gripper_ids)
        episode.initial_grippers = state.grippers.copy()
        policy = make_policy(env, state)
        record = _Recorder(state.cloth, episode.anchor_pc) if trajectory else None
        for t in range(steps):
            targets = policy.targets(state.cloth)
            if record is not None:
                record.add(state, targets)
            env.step(targets)
            state = env.state()
            if frame_every and render is not None and t % frame_every == 0:
                episode.frames.append(render(env))
        episode.goal_pc = state.cloth.copy()
        env.release()
        episode.released_pc = env.state().cloth.copy()
        if frame_every and render is not None:
            episode.frames.append(render(env))
        episode.checks = env.judge(episode.goal_pc, episode.released_pc)
        episode.success = episode.checks["success"]
        if record is not None:
            episode.trajectory = record.arrays()
    except SimulationExploded:
        episode.exploded, episode.success = True, False
    episode.seconds = time.perf_counter() - start
    return episode


def episode_to_demo(episode: Episode, task: str = "") -> dict:
    """The official demo layout (shared/data/tax3d-official/README.md), plus the task's name (when given) and
    optional traj_* arrays."""
    n = len(episode.action_pc)
    anchors = {
        int(gid): {"pos": episode.initial_grippers[i].astype(np.float64), "vertices": [int(v)]}
        for i, (gid, v) in enumerate(zip(episode.gripper_ids, episode.grip_vertices))
    }
    demo = {
        "action_pc": episode.action_pc.astype(np.float64),
        "action_seg": np.ones(n, dtype=np.float64),
        "anchor_pc": episode.anchor_pc.astype(np.float64),
        "anchor_seg": np.zeros(len(episode.anchor_pc), dtype=np.int32),
        "flow": (episode.goal_pc - episode.action_pc).astype(np.float64),
        "speed_factor": np.array(1.0),
        "rot": np.array([0.0, 0.0, episode.rot_z]),
        "trans": episode.trans.astype(np.float64),
        "deform_params": dict(episode.cloth_params),
        "anchors": anchors,
    }
    if task:
        demo["task"] = task
    demo.update({f"traj_{k}": v for k, v in episode.trajectory.items()})
    return demo


class _Recorder:
    """Per-step observations and actions for the DP3 baseline: grippers, velocities, targets, downsampled clouds."""

    def __init__(self, cloth: np.ndarray, anchor: np.ndarray):
        rng = np.random.default_rng(0)
        # The cloth keeps its correspondences, so one vertex subset chosen at reset serves every step.
        self.cloth_idx = _fps_numpy(cloth, min(TRAJECTORY_POINTS, len(cloth)), rng)
        self.anchor = anchor[_fps_numpy(anchor, min(TRAJECTORY_POINTS, len(anchor)), rng)]
        self.rows: dict[str, list] = {"gripper_pos": [], "gripper_vel": [], "targets": [], "action_pc": []}

    def add(self, state: SceneState, targets: np.ndarray) -> None:
        self.rows["gripper_pos"].append(state.grippers)
        self.rows["gripper_vel"].append(state.velocities)
        self.rows["targets"].append(np.asarray(targets))
        self.rows["action_pc"].append(state.cloth[self.cloth_idx])

    def arrays(self) -> dict:
        out = {k: np.asarray(v, dtype=np.float32) for k, v in self.rows.items()}
        out["action_idx"] = self.cloth_idx.astype(np.int64)
        out["anchor_pc"] = self.anchor.astype(np.float32)
        return out


def _fps_numpy(points: np.ndarray, k: int, rng: np.random.Generator) -> np.ndarray:
    chosen = np.empty(k, dtype=np.int64)
    chosen[0] = rng.integers(len(points))
    dist = np.full(len(points), np.inf)
    for i in range(1, k):
        dist = np.minimum(dist, ((points - points[chosen[i - 1]]) ** 2).sum(1))
        chosen[i] = int(dist.argmax())
    return chosen
