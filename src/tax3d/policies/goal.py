"""The goal-conditioned evaluation policy of appendix A.3: predicted grip-vertex positions become gripper targets."""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from tax3d.geometry import nearest_rows


@dataclass(frozen=True)
class Sampling:
    """How a goal policy samples its goals (`tax3d eval`'s options of the same names)."""

    samples: int = 1  # goal samples a prediction; the policy follows the first
    steps: int | None = None  # denoising steps (None: the checkpoint's)
    sampler: str | None = None  # ddpm or ddim (None: the checkpoint's)
    max_points: int | None = None  # the network runs on at most this many action points (None: the checkpoint's)
    seed: int = 0  # of the first prediction; each later one adds one
    replan_every: int = 0  # closed loop: predict again every K environment steps (0: open loop)


class GoalPolicy:
    """Predict the goal of every action point once (the network on at most the checkpoint's predict_points of them);
    drive the grippers to the predicted grip vertices.

    With sampling.replan_every = K > 0 it predicts again every K environment steps from the current cloth (closed loop,
    the paper's stated limitation; reported separately). `offset` is added to the predicted positions (HangBag:
    `tax3d.sim.bag.POLICY_OFFSET`). With several samples it follows the first, the paper's policy. Called as
    make_policy(env, state) by run_episode.

    `observe(env)`, when given, is the action cloud the policy sees instead of the mesh vertices (a camera's, from
    tax3d.sim.observe): the grippers then go to the predicted goals of the observed points nearest the grasped
    vertices, which the simulator knows.
    """

    def __init__(self, predictor, sampling: Sampling = Sampling(), trajectory: bool = False, offset=(0.0, 0.0, 0.0),
                 observe=None):
        self.predictor, self.sampling, self.observe = predictor, sampling, observe
        self.offset = np.asarray(offset, dtype=np.float64)
        self.trajectory = trajectory
        self.predict_seconds, self.predictions = 0.0, 0
        self.first_prediction: np.ndarray | None = None  # (S, N, 3) world-frame goal samples
        self.first_cloud: np.ndarray | None = None  # (N, 3) the action cloud they were predicted from
        self.grip: list[int] | None = None  # the action cloud's rows the grippers follow, from the first call
        self.denoising: np.ndarray | None = None  # (K, N, 3) intermediate goals of sample 0, noise to final

    def __call__(self, env, state):
        self.env, self.anchor = env, env.anchor_points()
        self.grip = list(env.mesh.grip_vertices())
        self.step = 0
        self._predict(state.cloth)
        return self

    def _seen(self, cloth: np.ndarray) -> np.ndarray:
        """The action cloud the policy predicts from; with a camera, the grip rows follow the grasped vertices."""
        if self.observe is None:
            return cloth
        seen = np.asarray(self.observe(self.env), dtype=np.float64)
        self.grip = nearest_rows(seen, cloth[list(self.env.mesh.grip_vertices())])
        return seen

    def _predict(self, cloth: np.ndarray) -> None:
        cloth = self._seen(cloth)
        start = time.perf_counter()
        s = self.sampling
        options = dict(num_samples=s.samples, steps=s.steps, sampler=s.sampler, seed=s.seed + self.predictions,
                       max_points=s.max_points)
        if self.trajectory and self.predictions == 0:
            goals, path = self.predictor.predict(cloth, self.anchor, return_trajectory=True, **options)
            self.denoising = path[:, 0]
        else:
            goals = self.predictor.predict(cloth, self.anchor, **options)
        self.predict_seconds += time.perf_counter() - start
        if self.predictions == 0:
            self.first_prediction, self.first_cloud = goals, cloth
        self.predictions += 1
        self.current = goals[0][self.grip] + self.offset

    def targets(self, cloth: np.ndarray) -> np.ndarray:
        every = self.sampling.replan_every
        if every and self.step and self.step % every == 0:
            self._predict(cloth)
        self.step += 1
        return self.current
