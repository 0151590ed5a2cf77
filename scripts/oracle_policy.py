"""Two fixed-goal predictors run through the evaluation policy: the demo's own goal (the ceiling) and the training
set's mean goal (the floor); writes JSON.

    python scripts/oracle_policy.py --task hangbag --data data/hangbag [--goal demo|mean] \\
        [--splits train,unseen,ood] [--offset 0 -0.5 1.0] [--workers 2] [--out FILE]

`--goal demo`: the goal a perfect predictor would return (the demonstration's action_pc + flow) replaces the model's
prediction; the rest of `tax3d eval` (episodes, gripper targets with the task's offset, success check) is unchanged,
so its success rate bounds what any predicted goal reaches with this policy and scene. `--goal mean`: the mean goal
of DATA/train in the anchor frame, placed at each scene's anchor (`tax3d.metrics.MeanGoalBaseline`), with its RMSE.
"""

from __future__ import annotations

import argparse
import functools
import json
import sys
from pathlib import Path

import numpy as np

from tax3d import provenance
from tax3d.atomic import write_text
from tax3d.errors import UsageError
from tax3d.evaluate import Args, EvalJob, cloth_key, plan_jobs, run_jobs, summarise
from tax3d.metrics import MeanGoalBaseline


class FixedGoal:
    """A predictor that returns a fixed goal cloud: the `predict` interface of `Tax3D`."""

    def __init__(self, goal: np.ndarray | None = None, mean: MeanGoalBaseline | None = None):
        self.goal, self.mean = goal, mean

    def predict(self, action_points, anchor_points, num_samples=1, steps=None, sampler=None, seed=None,
                return_trajectory=False):
        goal = self.mean.predict(action_points, anchor_points) if self.mean is not None else self.goal
        if len(action_points) != len(goal):
            raise ValueError(f"{len(action_points)} action points, but the goal has {len(goal)}")
        goals = np.repeat(np.asarray(goal, dtype=np.float64)[None], num_samples, axis=0)
        return (goals, goals[None]) if return_trajectory else goals


def fixed_goal_episode(job: EvalJob, offset: tuple, mean: MeanGoalBaseline | None) -> dict:
    from tax3d.metrics import rmse
    from tax3d.policy import GoalPolicy
    from tax3d.sim.scenes import process_env
    from tax3d.sim.episode import run_episode
    from tax3d.sim.tasks import get_task

    task = get_task(job.task)
    predictor = FixedGoal(mean=mean) if mean is not None else FixedGoal(goal=job.true_goal)
    policy = GoalPolicy(predictor, offset=task.policy_offset if offset is None else offset)
    ep = run_episode(process_env(job.floor, task.scene), job.cloth_params, job.rot_z, job.trans, policy)
    pred = policy.first_prediction
    error = None if pred is None else float(rmse(pred[0], job.true_goal))
    return {"split": job.split, "name": job.name, "success": bool(ep.success), "exploded": bool(ep.exploded),
            "seconds": ep.seconds, "rmse": error, "pred_goal": pred, "true_goal": job.true_goal,
            "cloth_key": cloth_key(job), "predict_seconds": 0.0, "sim_seconds": ep.seconds}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--task", default="hangbag")
    parser.add_argument("--data", type=Path, required=True, help="folder with a demo sub-folder per split")
    parser.add_argument("--goal", choices=("demo", "mean"), default="demo", help="demo: each demo's own goal; "
                        "mean: the mean goal of DATA/train in the anchor frame")
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
        mean = None
        if args.goal == "mean":
            from tax3d.data.format import list_demos, load_demo

            if not (args.data / "train").is_dir():
                raise UsageError(f"--data {args.data}: no train folder to take the mean goal from")
            try:
                mean = MeanGoalBaseline.fit([load_demo(p) for p in list_demos(args.data / "train")])
            except ValueError as err:
                raise UsageError(f"--data {args.data / 'train'}: {err}") from None
    except UsageError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    offset = None if args.offset is None else tuple(args.offset)
    results = run_jobs(jobs, args.workers, fn=functools.partial(fixed_goal_episode, offset=offset, mean=mean))
    from tax3d.sim.tasks import get_task

    names = list(dict.fromkeys(j.split for j in jobs))
    table = summarise(results, names)
    splits = {}
    for name in names:
        rows = [r for r in results if r["split"] == name]
        t = table[name]
        # coverage / precision RMSE over each cloth's demonstrated goals (multimodal: one per hole)
        splits[name] = {"episodes": t["episodes"], "success_rate": t["success_rate"], "rmse": t["rmse"],
                        "coverage_rmse": t["coverage_rmse"], "precision_rmse": t["precision_rmse"],
                        "failures": [r["name"] for r in rows if not r["success"]],
                        "exploded": sum(1 for r in rows if r["exploded"] or r.get("error"))}
    out = {"command": "python " + " ".join(sys.argv), "task": args.task, "goal": args.goal,
           "offset": list(offset if offset is not None else get_task(args.task).policy_offset),
           "machine": provenance.machine(),
           "date": provenance.today(), "splits": splits}
    text = json.dumps(out, indent=2)
    if args.out is not None:
        write_text(args.out, text + "\n")
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
