"""The evaluation policy's ceiling: each demo's own goal, executed by the goal-conditioned policy; writes JSON.

    python scripts/oracle_policy.py --task hangbag --data data/hangbag --splits train,unseen,ood \\
        [--offset 0 -0.5 1.0] [--workers 2] [--out docs/results/hangbag_oracle.json]

The goal a perfect predictor would return (the demonstration's action_pc + flow) replaces the model's prediction;
the rest of `tax3d eval` (episodes, gripper targets with the task's offset, success check) is unchanged. Its
success rate bounds what any predicted goal can reach with this policy and scene.
"""

from __future__ import annotations

import argparse
import datetime
import functools
import json
import os
import platform
import sys
from pathlib import Path

import numpy as np

from tax3d.atomic import write_text
from tax3d.errors import UsageError
from tax3d.evaluate import Args, EvalJob, plan_jobs, run_jobs


class DemoGoal:
    """A predictor that returns a fixed goal cloud: the `predict` interface of `Tax3D`."""

    def __init__(self, goal: np.ndarray):
        self.goal = np.asarray(goal, dtype=np.float64)

    def predict(self, action_points, anchor_points, num_samples=1, steps=None, seed=None, return_trajectory=False):
        if len(action_points) != len(self.goal):
            raise ValueError(f"{len(action_points)} action points, but the demo's goal has {len(self.goal)}")
        goals = np.repeat(self.goal[None], num_samples, axis=0)
        return (goals, goals[None]) if return_trajectory else goals


def oracle_episode(job: EvalJob, offset: tuple) -> dict:
    from tax3d.policy import GoalPolicy
    from tax3d.sim.env import process_env
    from tax3d.sim.episode import run_episode
    from tax3d.sim.tasks import get_task

    task = get_task(job.task)
    policy = GoalPolicy(DemoGoal(job.true_goal), offset=task.policy_offset if offset is None else offset)
    ep = run_episode(process_env(job.floor, task.scene), job.cloth_params, job.rot_z, job.trans, policy)
    return {"split": job.split, "name": job.name, "success": bool(ep.success), "exploded": bool(ep.exploded),
            "seconds": ep.seconds}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--task", default="hangbag")
    parser.add_argument("--data", type=Path, required=True, help="folder with a demo sub-folder per split")
    parser.add_argument("--splits", default="train,unseen,ood")
    parser.add_argument("--episodes", type=int, default=None, help="episodes per split (default: every demo)")
    parser.add_argument("--offset", type=float, nargs=3, default=None, help="gripper-target offset (default: the "
                        "task's)")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--out", type=Path, default=None, help="write the JSON here too")
    args = parser.parse_args()
    try:
        if not args.data.is_dir():
            raise UsageError(f"--data {args.data}: no such folder; expected one demo folder per split inside it")
        jobs = plan_jobs(Args(checkpoint=Path("-"), task=args.task, splits=args.splits, data=args.data,
                              episodes=args.episodes))
        if any(j.true_goal is None for j in jobs):
            raise UsageError(f"--data {args.data}: every split needs a demo folder (the goals come from the demos)")
    except UsageError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    offset = None if args.offset is None else tuple(args.offset)
    results = run_jobs(jobs, args.workers, fn=functools.partial(oracle_episode, offset=offset))
    from tax3d.sim.tasks import get_task

    splits = {}
    for name in dict.fromkeys(j.split for j in jobs):
        rows = [r for r in results if r["split"] == name]
        splits[name] = {"episodes": len(rows), "success_rate": float(np.mean([r["success"] for r in rows])),
                        "failures": [r["name"] for r in rows if not r["success"]],
                        "exploded": sum(1 for r in rows if r["exploded"] or r.get("error"))}
    out = {"command": "python " + " ".join(sys.argv), "task": args.task,
           "offset": list(offset if offset is not None else get_task(args.task).policy_offset),
           "machine": f"{platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}",
           "date": datetime.date.today().isoformat(), "splits": splits}
    text = json.dumps(out, indent=2)
    if args.out is not None:
        write_text(args.out, text + "\n")
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
