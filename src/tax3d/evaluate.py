"""`tax3d eval`: a checkpoint predicts goals, the policy executes them in the simulator, the success check judges.

The environment runner (this module) is separate from the policy it evaluates (`tax3d.policies`). OUT gets results.json
(the summary and every episode), summary.json (the summary alone: kept JSON of kind "eval", tax3d.kept) and the
report.
"""

from __future__ import annotations


import json
import sys
import warnings
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Annotated, Literal

import numpy as np

from tax3d import kept, provenance
from tax3d.atomic import write_text
from tax3d.episodes import Episodes
from tax3d.errors import UsageError
from tax3d.options import Finite, NonNegative, OutputFolder, Positive
from tax3d.parallel import check_backend, run_each
from tax3d.policies.fixed import FixedGoal
from tax3d.policies.load import check_sampling, load_model, policy_for
from tax3d.sim.observe import CameraSpec

# The official data's `val_ood` folder holds out-of-distribution poses; its `val` folder is evaluated as `val`.
SPLIT_FOLDERS = {"train": ("train",), "val": ("val",), "unseen": ("unseen",), "ood": ("ood", "val_ood")}


@dataclass
class Args:
    """Evaluate a checkpoint on HangProcCloth or HangBag: RMSE and policy success per split, a table, JSON, a report."""

    checkpoint: Path | None = None
    """checkpoint directory (config.json + model.safetensors); not with --goal demo or mean"""
    goal: Literal["model", "demo", "mean"] = "model"
    """whose goal the policy executes: the checkpoint's prediction; each demo's own goal (the policy's ceiling); or
    the mean goal of DATA/train in the anchor frame (the floor); demo and mean need --data"""
    task: str = "hangproccloth-simple"
    """hangproccloth-simple, hangproccloth-unimodal, hangproccloth-multimodal or hangbag"""
    splits: str = "train,unseen,ood"
    """comma-separated splits to evaluate"""
    data: Path | None = None
    """folder with a demo sub-folder per split (train, val, unseen, ood; the official data's val_ood serves as ood):
    its episodes are replayed and their goals scored; a split without a folder gets fresh anchor poses from the
    split's seeds (success only)"""
    episodes: Annotated[int | None, Positive] = None
    """episodes per split (default: every demo of the split's folder, or the paper's size)"""
    samples: Annotated[int, Positive] = 1
    """goal samples per episode (the policy executes the first, the paper's policy); RMSE is their mean, coverage
    their min"""
    steps: Annotated[int | None, Positive] = None
    """denoising steps (default: the checkpoint's)"""
    sampler: Literal["ddpm", "ddim"] | None = None
    """ddpm or ddim (default: the checkpoint's diffusion.sampler)"""
    max_points: Annotated[int | None, NonNegative] = None
    """the network runs on at most this many action points, the others taking the displacement of their nearest
    sampled ones (default: the checkpoint's data.predict_points, else the number it was trained on; 0: every
    point; as `tax3d predict --max-points`)"""
    replan_every: Annotated[int, NonNegative] = 0
    """closed loop: predict again every K environment steps (0: open loop, the paper's policy)"""
    workers: Annotated[int, Positive] = 2
    """worker processes, each with its own simulator and a copy of the model"""
    backend: Literal["local", "ray"] = "local"
    """local: a process pool on this machine; ray: Ray tasks (a local Ray instance, or the cluster at --address)"""
    address: str | None = None
    """with --backend ray: the address of an existing Ray cluster (default: start a local one)"""
    device: str = "cpu"
    """where each worker's model predicts: cpu, cuda, cuda:K or auto (CUDA when there is one)"""
    first_index: Annotated[int, NonNegative] = 0
    """index of the first episode of each split: with --data, demo_FIRST.npz and the files after it (the table's
    test episodes: 100); without a demo folder, the first fresh episode"""
    seed: int = 0
    """seed of each episode's prediction, plus the episode's index: the same seed, the same goals"""
    policy_offset: Annotated[tuple[float, float, float] | None, Finite] = None
    """added to the predicted grip-vertex positions to make the gripper targets (default: the task's)"""
    out: Annotated[Path, OutputFolder] = Path("out/eval")
    """output folder: results.json, summary.json (kept JSON: the summary alone), report.html, images/"""
    report: bool = True
    """write the HTML report"""
    observe: Literal["mesh", "camera"] = "mesh"
    """what the policy sees of the deformable: its mesh vertices, or depth cameras' cloud at the start (the grippers
    go to the predicted goals of the observed points nearest the grasped vertices); with --data, the demos' own
    action_pc is the camera's cloud (`tax3d generate --camera-out`), without it the cameras of --camera.* look"""
    camera: CameraSpec = field(default_factory=CameraSpec)
    """with --observe camera and no demo folder for a split: the cameras (as `tax3d generate --camera.*`)"""


@dataclass
class EvalJob:
    split: str
    name: str
    cloth_params: dict
    rot_z: float
    trans: list
    floor: bool
    checkpoint: str
    true_goal: np.ndarray | None = None
    samples: int = 1
    steps: int | None = None
    sampler: str | None = None
    max_points: int | None = None
    replan_every: int = 0
    seed: int = 0
    denoising: bool = False
    task: str = "hangproccloth-simple"
    offset: tuple | None = None  # gripper-target offset; None: the task's
    device: str = "cpu"
    goal: str = "model"  # model, demo or mean (Args.goal)
    mean_goal: object = None  # with goal "mean": the MeanGoalBaseline fitted on the training demos
    observe: str = "mesh"  # Args.observe
    camera: object = None  # observe "camera": the CameraSpec
    observation: np.ndarray | None = None  # observe "camera" with a demo: its action_pc, the camera's cloud
    cloth_index: int = 0  # which cloth of the split: seeds the camera noise as `tax3d generate` does


_PREDICTORS: dict = {}


def _predictor(checkpoint: str, device: str = "cpu"):
    if (checkpoint, device) not in _PREDICTORS:
        import torch

        torch.set_num_threads(1)
        _PREDICTORS[checkpoint, device] = load_model(checkpoint, device)
    return _PREDICTORS[checkpoint, device]


def run_eval_job(job: EvalJob) -> dict:
    """One evaluation episode in this process: predict, execute open or closed loop, release, judge. The warnings
    it raises come back in the result ("warnings"), for the command to say once in its own words: a worker process
    has neither the command's warning format nor its sense of what was said already."""
    with warnings.catch_warnings(record=True) as caught:  # under the filters in force: what would be shown
        result = episode(job)
    result["warnings"] = list(dict.fromkeys(str(w.message) for w in caught))
    return result


def episode(job: EvalJob) -> dict:
    from tax3d.metrics import grip_error, rmse
    from tax3d.sim.scenes import process_env
    from tax3d.sim.episode import run_episode
    from tax3d.sim.tasks import get_task

    task = get_task(job.task)
    if job.goal == "model":
        predictor = _predictor(job.checkpoint, job.device)
    else:
        predictor = FixedGoal(job.true_goal if job.goal == "demo" else job.mean_goal)
    policy = policy_for(predictor, job.samples, job.steps, job.seed, job.replan_every, trajectory=job.denoising,
                        offset=task.policy_offset if job.offset is None else job.offset, sampler=job.sampler,
                        max_points=job.max_points, observe=_camera(job) if job.observe == "camera" else None)
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
    from tax3d.sim.observe import camera_seed, observe

    rng = camera_seed(job.task, job.split, job.cloth_index)
    first = [] if job.observation is None else [job.observation]

    def seen(env):
        return first.pop() if first else observe(env, job.camera, rng).points

    return seen


def cloth_key(job: EvalJob) -> str:
    """Episodes with the same cloth and anchor pose share a key: their goals are one cloth's modes (appendix C)."""
    return json.dumps([job.split, job.cloth_params, round(job.rot_z, 9), [round(t, 9) for t in job.trans]])


def _split_folder(data: Path | None, split: str) -> Path | None:
    if data is None:
        return None
    for name in SPLIT_FOLDERS[split]:
        if (data / name).is_dir():
            return data / name
    return None


def plan_jobs(args: Args) -> list[EvalJob]:
    from tax3d.data.format import demo_index, load_demo
    from tax3d.sim.tasks import episode_params, get_split, get_task

    task = get_task(args.task)
    if args.episodes is not None and args.episodes < 1:
        raise UsageError(f"--episodes {args.episodes}: expected at least 1 episode per split")
    split_names = [s.strip() for s in args.splits.split(",") if s.strip()]
    canonical = [get_split(name).name for name in split_names]
    twice = next((name for i, name in enumerate(canonical) if name in canonical[:i]), None)
    if twice is not None:
        raise UsageError(f"--splits {args.splits!r}: {twice} is named twice; expected each split once (its episodes "
                         f"would be scored twice)")
    if args.data is not None:
        if not args.data.is_dir():
            raise UsageError(f"--data {args.data}: no such folder; expected one demo folder per split inside it")
        wanted = [name for split_name in split_names for name in SPLIT_FOLDERS[get_split(split_name).name]]
        if next(args.data.glob("demo_*.npz"), None) is not None:
            raise UsageError(f"--data {args.data}: holds demo files itself; expected the folder above it, with a "
                             f"folder per split ({', '.join(dict.fromkeys(wanted))})")
        if all(_split_folder(args.data, get_split(name).name) is None for name in split_names):
            raise UsageError(f"--data {args.data}: has none of the folders {', '.join(dict.fromkeys(wanted))}; "
                             f"expected a demo folder per split inside it")
    mean_goal = _fixed_goal(args, split_names) if args.goal != "model" else None
    jobs = []
    for split_name in split_names:
        split = get_split(split_name)
        folder = _split_folder(args.data, split.name)
        common = dict(checkpoint=str(args.checkpoint), samples=args.samples, steps=args.steps,
                      sampler=args.sampler, max_points=args.max_points, replan_every=args.replan_every,
                      task=task.name, device=args.device,
                      offset=None if args.policy_offset is None else tuple(float(v) for v in args.policy_offset),
                      goal=args.goal, mean_goal=mean_goal, observe=args.observe, camera=args.camera)
        if folder is not None:
            paths = _demos_from(folder, args.first_index, args.episodes)
            for path in paths:
                demo = load_demo(path)
                trans = demo["trans"]
                floor = bool(demo["anchor_pc"][:, 2].min() >= trans[2] - 0.05)
                jobs.append(EvalJob(split.name, path.stem, demo["deform_params"], float(demo["rot"][2]),
                                    trans.tolist(), floor, true_goal=demo["action_pc"] + demo["flow"],
                                    seed=args.seed + demo_index(path),
                                    cloth_index=demo_index(path) // task.demos_per_cloth,
                                    observation=demo["action_pc"] if args.observe == "camera" else None, **common))
        else:
            num = task.sizes[split.name] if args.episodes is None else args.episodes
            for i in range(args.first_index, args.first_index + num):
                params = episode_params(task, split, i // task.demos_per_cloth)
                jobs.append(EvalJob(split.name, f"episode_{i}", params.cloth_params, params.rot_z,
                                    params.trans.tolist(), True, seed=args.seed + i,
                                    cloth_index=i // task.demos_per_cloth, **common))
    if not jobs:
        raise UsageError(f"--splits {args.splits!r}: no episodes to evaluate")
    jobs[0].denoising = True
    return jobs


def _demos_from(folder: Path, first: int, episodes: int | None) -> list[Path]:
    """The demo files of a split folder with index FIRST to FIRST + EPISODES - 1 (default: every index from FIRST
    on); the summary counts the episodes found."""
    from tax3d.data.format import demo_index, list_demos

    end = None if episodes is None else first + episodes
    paths = [p for p in list_demos(folder) if demo_index(p) >= first and (end is None or demo_index(p) < end)]
    if not paths:
        raise UsageError(f"--data {folder}: no demo files from demo_{first}.npz on; expected demos at or after "
                         f"--first-index {first}")
    return paths


def _fixed_goal(args: Args, split_names: list[str]):
    """--goal demo or mean: check that every split has its demos; for mean, fit the training set's mean goal."""
    from tax3d.data.format import list_demos, load_demo
    from tax3d.metrics import MeanGoalBaseline
    from tax3d.sim.tasks import get_split

    if args.data is None:
        raise UsageError(f"--goal {args.goal}: needs --data, the folder of the demos whose goals it executes")
    missing = [name for name in split_names if _split_folder(args.data, get_split(name).name) is None]
    if missing:
        raise UsageError(f"--goal {args.goal}: --data {args.data} has no demo folder for {', '.join(missing)}; "
                         f"expected one per split, the goals come from the demos")
    if args.goal == "demo":
        return None
    train = _split_folder(args.data, "train")
    if train is None:
        raise UsageError(f"--goal mean: --data {args.data} has no train folder to take the mean goal from")
    try:
        return MeanGoalBaseline.fit([load_demo(path) for path in list_demos(train)])
    except ValueError as err:
        raise UsageError(f"--data {train}: {err}") from None


def run_jobs(jobs: list[EvalJob], workers: int, progress: bool = True, fn=run_eval_job, backend: str = "local",
             address: str | None = None, kept: Episodes | None = None) -> list[dict]:
    """Episodes in worker processes (or Ray tasks); an episode that raises, or whose worker dies, is marked failed:
    no hang, and the other episodes go on. With `kept`, the episodes kept there are not run again, and each one run
    is kept as it finishes."""
    from tqdm import tqdm

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
        results.append(result if error is None else _failed(todo[i], f"{type(error).__name__}: {error}"))
        bar.update()
    bar.close()
    for message, count in said.items():
        warnings.warn(f"{message} (in {count} of {len(todo)} episodes)", stacklevel=2)
    order = {(j.split, j.name): i for i, j in enumerate(jobs)}
    return sorted(results, key=lambda r: order[(r["split"], r["name"])])


def _failed(job: EvalJob, why: str) -> dict:
    return {"split": job.split, "name": job.name, "success": False, "exploded": False, "error": why, "rmse": None,
            "min_rmse": None, "executed_rmse": None, "executed_grip_error": None, "predict_seconds": 0.0,
            "sim_seconds": 0.0, "checks": {}, "action_pc": None, "anchor_pc": None, "pred_goal": None,
            "true_goal": job.true_goal, "released_pc": None, "grip_vertices": [], "denoising": None,
            "cloth_key": cloth_key(job)}


def summarise(results: list[dict], splits: list[str]) -> dict:
    """Per split: success rate, RMSE, and coverage / precision RMSE over each cloth's goals (appendix C)."""
    from tax3d.metrics import coverage_rmse, precision_rmse, success_interval

    table = {}
    for split in splits:
        rows = [r for r in results if r["split"] == split]
        if not rows:
            continue
        scored = [r["rmse"] for r in rows if r["rmse"] is not None]
        executed = [r["executed_rmse"] for r in rows if r.get("executed_rmse") is not None]
        grips = [r["executed_grip_error"] for r in rows if r.get("executed_grip_error") is not None]
        clothes: dict[str, list[dict]] = {}
        for r in rows:
            if r["true_goal"] is not None and r["pred_goal"] is not None:
                clothes.setdefault(r["cloth_key"], []).append(r)
        coverage, precision = [], []
        for group in clothes.values():
            samples = np.concatenate([r["pred_goal"] for r in group])
            goals = np.stack([r["true_goal"] for r in group])
            coverage.append(float(coverage_rmse(samples, goals)))
            precision.append(float(precision_rmse(samples, goals)))
        table[split] = {
            "episodes": len(rows),
            "success_rate": float(np.mean([r["success"] for r in rows])),
            "success_ci95": list(success_interval(sum(bool(r["success"]) for r in rows), len(rows))),
            "rmse": float(np.mean(scored)) if scored else None,
            "executed_rmse": float(np.mean(executed)) if executed else None,
            "executed_grip_error": float(np.mean(grips)) if grips else None,
            "coverage_rmse": float(np.mean(coverage)) if coverage else None,
            "precision_rmse": float(np.mean(precision)) if precision else None,
            "predict_seconds": float(np.mean([r["predict_seconds"] for r in rows])),
            "sim_seconds": float(np.mean([r["sim_seconds"] for r in rows])),
            "failed_runs": sum(1 for r in rows if r.get("error") or r["exploded"]),
        }
    return table


def display_name(variant: str) -> str:
    names = {"dp3": "DP3", "demo-goal": "Each demo's own goal", "mean-goal": "The training set's mean goal"}
    return names.get(variant, f"TAX3D-{variant.upper()}")


def format_table(table: dict) -> str:
    splits = list(table)
    lines = [f"{'':<14}" + "".join(f"{s:>10}" for s in splits)]
    for label, key, fmt in (("RMSE", "rmse", "{:.3f}"), ("Success rate", "success_rate", "{:.2f}"),
                            ("Coverage RMSE", "coverage_rmse", "{:.3f}"), ("Precision RMSE", "precision_rmse", "{:.3f}")):
        if key != "success_rate" and key != "rmse" and all(table[s][key] is None for s in splits):
            continue
        cells = ["-" if table[s][key] is None else fmt.format(table[s][key]) for s in splits]
        lines.append(f"{label:<14}" + "".join(f"{c:>10}" for c in cells))
    return "\n".join(lines)


def evaluate(args: Args, progress: bool = True, record: bool = True) -> dict:
    """Run the episodes and write the outputs; a scoring of test episodes goes in the ledger first (tax3d.ledger),
    unless `record` is False (`tax3d table` writes its own line, with the row)."""
    from tax3d.sim.tasks import get_task

    get_task(args.task)
    check_backend(args.backend, args.workers, args.address)
    if args.samples < 1:
        raise UsageError(f"--samples {args.samples}: expected at least 1")
    if args.observe == "camera" and not args.camera.views:
        raise UsageError("--camera.views: none given; expected one or more of front, front-left, front-right, back")
    if args.goal == "model":
        if args.checkpoint is None:
            raise UsageError("--checkpoint: missing; expected a checkpoint folder (or --goal demo or mean with --data)")
        model = load_model(args.checkpoint, args.device)  # fails early, in one line, on a bad checkpoint or device
        _check_task(model, args)
        check_sampling(model, args.steps, args.sampler)
        variant = model.config.model.variant
    elif args.checkpoint is not None:
        raise UsageError(f"--checkpoint {args.checkpoint}: not used with --goal {args.goal}; expected one or the other")
    else:
        variant = f"{args.goal}-goal"
    jobs = plan_jobs(args)
    sha = None if args.checkpoint is None else _weights_sha256(args.checkpoint)
    kept = Episodes(args.out, sha)
    results = run_jobs(jobs, args.workers, progress, backend=args.backend, address=args.address, kept=kept)
    splits = list(dict.fromkeys(j.split for j in jobs))
    summary = {
        "checkpoint": None if args.checkpoint is None else str(args.checkpoint), "task": args.task,
        "weights_sha256": sha,
        "variant": variant, "goal": args.goal,
        **provenance.made("tax3d.evaluate"), "args": {k: str(v) for k, v in asdict(args).items()},
        "splits": summarise(results, splits),
        "policy_offset": list(get_task(args.task).policy_offset if args.policy_offset is None else args.policy_offset),
    }
    if record:
        from tax3d.ledger import record_eval

        record_eval(args, summary, lambda split: _demos_from(_split_folder(args.data, split), args.first_index,
                                                             args.episodes))
    _write_outputs(args, summary, results)
    kept.remove()
    return {"summary": summary, "results": results}


def _weights_sha256(checkpoint: Path) -> str:
    """The sha256 of the evaluated weights file, so a summary names exactly the weights it scored."""
    from tax3d.checkpoint import WEIGHTS_NAME, sha256

    return sha256(Path(checkpoint) / WEIGHTS_NAME)


def _check_task(model, args: Args) -> None:
    """The checkpoint must record the task it was trained on (data.task of its config.json), and it must be --task."""
    trained_on = getattr(model.config.data, "task", "") or ""
    if trained_on in ("", "custom"):
        what = "no recorded task" if not trained_on else "custom demonstrations (their files name no task)"
        raise UsageError(f"--checkpoint {args.checkpoint}: trained on {what}, not known to be {args.task!r}; "
                         f"expected a checkpoint whose config.json records data.task {args.task!r} (train on "
                         f"`tax3d generate` demos, or with --data.task {args.task})")
    if trained_on != args.task:
        raise UsageError(f"--checkpoint {args.checkpoint}: trained for task {trained_on!r}, not {args.task!r}; "
                         f"expected --task {trained_on} or a checkpoint trained on {args.task}")


def _write_outputs(args: Args, summary: dict, results: list[dict]) -> None:
    args.out.mkdir(parents=True, exist_ok=True)
    scalars = [{k: v for k, v in r.items() if not isinstance(v, np.ndarray) and k not in ("cloth_key",)}
               for r in results]
    path = args.out / "results.json"
    write_text(path, json.dumps({"summary": summary, "episodes": scalars}, indent=2, default=_plain))
    # the kept JSON of the evaluation: its summary without the episodes
    write_text(args.out / "summary.json", json.dumps(kept.stamp("eval", 1, {"summary": summary}), indent=1,
                                                     default=_plain) + "\n")
    if args.report:
        from tax3d.report import write_report

        episodes = [r for r in results if r["action_pc"] is not None]
        write_report(args.out, summary, episodes, title=f"{display_name(summary['variant'])} on {args.task}")


def _plain(value):
    if isinstance(value, (np.generic,)):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    raise TypeError(f"cannot serialise {type(value)}")


def run(args: Args) -> int:
    out = evaluate(args)
    summary = out["summary"]
    source = f"checkpoint {args.checkpoint}" if args.goal == "model" else f"the demos in {args.data}"
    print(f"{display_name(summary['variant'])} on {args.task}, {source}")
    print(format_table(summary["splits"]))
    failed = sum(s["failed_runs"] for s in summary["splits"].values())
    if failed:
        print(f"{failed} episodes ended early (cloth exploded or flung far, or a worker died); counted as failures")
    print(f"results: {args.out / 'results.json'}")
    if args.report:
        print(f"report: {args.out / 'report.html'}")
    return 0
