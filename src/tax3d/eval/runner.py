"""One evaluation episode (predict, execute open or closed loop, release, judge) and the episodes over workers."""

from __future__ import annotations

import sys
import warnings

from tqdm import tqdm

from tax3d.eval.episodes import Episodes
from tax3d.eval.jobs import EvalJob, cloth_key
from tax3d.metrics import grip_error, rmse
from tax3d.parallel import run_each
from tax3d.policies.load import load_policy
from tax3d.sim.episode import run_episode
from tax3d.sim.observe import camera_seed, observe
from tax3d.sim.scenes import process_env
from tax3d.sim.tasks import get_task


def run_eval_job(job: EvalJob) -> dict:
    """One evaluation episode in this process. The warnings it raises come back in the result ("warnings"), for the
    command to say once in its own words: a worker process has neither the command's warning format nor its sense
    of what was said already."""
    with warnings.catch_warnings(record=True) as caught:  # under the filters in force: what would be shown
        result = episode(job)
    result["warnings"] = list(dict.fromkeys(str(w.message) for w in caught))
    return result


def episode(job: EvalJob) -> dict:
    task = get_task(job.task)
    policy = load_policy(job.policy_goal(), job.sampling, job.device, trajectory=job.denoising,
                         offset=task.policy_offset if job.offset is None else job.offset,
                         observe=_camera(job) if job.observe == "camera" else None)
    ep = run_episode(process_env(job.floor, task.scene), job.cloth_params, job.rot_z, job.trans, policy)
    pred = policy.first_prediction
    errors = None if job.true_goal is None or pred is None else rmse(pred, job.true_goal[None])
    # the policy executes the first sample, at the rows it takes for the grasped vertices
    grip = list(ep.grip_vertices if policy.grip is None else policy.grip)
    seen = policy.first_cloud
    executed_grip_error = None if errors is None or not grip else grip_error(pred[0], job.true_goal, grip)
    return {
        "split": job.split, "name": job.name, "success": bool(ep.success), "exploded": bool(ep.exploded),
        "rmse": None if errors is None else float(errors.mean()),
        "min_rmse": None if errors is None else float(errors.min()),
        "executed_rmse": None if errors is None else float(errors[0]), "executed_grip_error": executed_grip_error,
        "predict_seconds": policy.predict_seconds, "sim_seconds": ep.seconds - policy.predict_seconds,
        "checks": ep.checks, "action_pc": ep.action_pc if seen is None else seen, "anchor_pc": ep.anchor_pc,
        "pred_goal": pred,
        "true_goal": job.true_goal, "released_pc": ep.released_pc, "grip_vertices": grip,
        "denoising": policy.denoising, "cloth_key": cloth_key(job),
    }


def _camera(job: EvalJob):
    """What a camera-observing policy sees: the demo's cloud at the start (the one its goals belong to), else, and on
    replanning, the cameras' view of the scene now."""
    rng = camera_seed(job.task, job.split, job.cloth_index)
    first = [] if job.observation is None else [job.observation]

    def seen(env):
        return first.pop() if first else observe(env, job.camera, rng).points

    return seen


def run_jobs(jobs: list[EvalJob], workers: int, progress: bool = True, fn=run_eval_job, backend: str = "local",
             address: str | None = None, kept: Episodes | None = None) -> list[dict]:
    """Episodes in worker processes (or Ray tasks); an episode that raises, or whose worker dies, is marked failed:
    no hang, and the other episodes go on. With `kept`, the episodes kept there are not run again, and each one run
    is kept as it finishes."""
    results = [r for r in (kept.load(job) for job in jobs) if r is not None] if kept is not None else []
    done = {(r["split"], r["name"]) for r in results}
    todo = [job for job in jobs if (job.split, job.name) not in done]
    if results and progress:
        print(f"{len(results)} of {len(jobs)} episodes kept in {kept.folder} from an interrupted run: "
              f"scoring the other {len(todo)}", file=sys.stderr)
    bar = tqdm(total=len(jobs), initial=len(results), desc="episodes", unit="ep", disable=not progress,
               file=sys.stderr)
    said: dict[str, int] = {}
    for i, result, error in run_each(fn, todo, workers, backend, address):
        if error is None:
            for message in result.pop("warnings", []):
                said[message] = said.get(message, 0) + 1
            if kept is not None:
                kept.keep(todo[i], result)
        results.append(result if error is None else failed(todo[i], f"{type(error).__name__}: {error}"))
        bar.update()
    bar.close()
    for message, count in said.items():
        warnings.warn(f"{message} (in {count} of {len(todo)} episodes)", stacklevel=2)
    order = {(j.split, j.name): i for i, j in enumerate(jobs)}
    return sorted(results, key=lambda r: order[(r["split"], r["name"])])


def failed(job: EvalJob, why: str) -> dict:
    """The result of an episode that raised or whose worker died: a failure, with nothing predicted."""
    return {"split": job.split, "name": job.name, "success": False, "exploded": False, "error": why, "rmse": None,
            "min_rmse": None, "executed_rmse": None, "executed_grip_error": None, "predict_seconds": 0.0,
            "sim_seconds": 0.0, "checks": {}, "action_pc": None, "anchor_pc": None, "pred_goal": None,
            "true_goal": job.true_goal, "released_pc": None, "grip_vertices": [], "denoising": None,
            "cloth_key": cloth_key(job)}
