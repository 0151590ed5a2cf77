"""Pseudo-expert demonstrations in the official layout, resumable, in worker processes (`tax3d generate`)."""

from __future__ import annotations


import math
import sys
import tempfile
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Annotated, Literal

import numpy as np
from tqdm import tqdm

from tax3d.data.format import SIM_KEYS, demo_index, is_valid_demo, list_demos, load_demo, save_demo
from tax3d.errors import UsageError
from tax3d.parallel import check_backend, run_each
from tax3d.sim.bag import parse_bag_params
from tax3d.sim.cloth import validate_cloth_params
from tax3d.sim.episode import episode_to_demo, expert_policy, run_episode
from tax3d.sim.observe import CameraSpec, camera_demo, camera_seed
from tax3d.sim.render import render_frame, save_frames
from tax3d.sim.scenes import process_env
from tax3d.sim.tasks import episode_params, get_split, get_task
from tax3d import options
from tax3d.options import NonNegative, OutputFolder, Positive


@dataclass
class Args:
    """Generate HangProcCloth or HangBag demonstrations, or replay the cloths and anchor poses of demo files."""

    task: str = "hangproccloth-simple"
    """hangproccloth-simple, hangproccloth-unimodal, hangproccloth-multimodal or hangbag (with --replay: the task
    the files come from)"""
    split: str = "train"
    """train, val (the split choices are made on), unseen or ood (out-of-distribution anchor poses)"""
    first_index: Annotated[int, NonNegative] = 0
    """index of the first demonstration (demo_FIRST.npz ...): the table's test episodes start at 100; multimodal
    needs an even index (two demonstrations share a cloth)"""
    num: Annotated[int | None, Positive] = None
    """number of demonstrations (with --replay: the first NUM files); default: the paper's size, or all files"""
    out: Annotated[Path, OutputFolder] = Path("data/demos")
    """output folder for demo_N.npz files"""
    workers: Annotated[int, Positive] = 1
    """worker processes, each with its own PyBullet world and temporary mesh folder"""
    backend: Literal["local", "ray"] = "local"
    """local: a process pool on this machine; ray: Ray tasks (a local Ray instance, or the cluster at --address)"""
    address: str | None = None
    """with --backend ray: the address of an existing Ray cluster (default: start a local one)"""
    replay: Path | None = None
    """re-run the cloth parameters and anchor poses of the demo files in this folder"""
    max_attempts: Annotated[int, Positive] = 5
    """an index whose expert episode fails is resampled up to this many times"""
    trajectories: bool = False
    """also store per-step gripper positions, velocities, targets and downsampled clouds (traj_* keys)"""
    render: Literal["none", "png", "gif"] = "none"
    """write pictures of each episode under OUT/renders"""
    render_every: Annotated[int, Positive] = 10
    """environment steps between rendered frames"""
    floor: bool = True
    """a floor plane at z = 0 (replay decides this per file from its anchor cloud)"""
    steps: Annotated[int, Positive] = 300
    """environment steps of manipulation per episode (the paper's episodes: 300)"""
    camera_out: Annotated[Path | None, OutputFolder] = None
    """also write each demo as depth cameras see the deformable at the start, under the same name in this folder:
    the same file format, action_pc the observed points and flow to their goals (docs/own-data.md); demos already
    in OUT get theirs without simulating again"""
    camera: CameraSpec = field(default_factory=CameraSpec)
    """the cameras of --camera-out"""

    def conflicts(self):
        per = get_task(self.task).demos_per_cloth
        if self.first_index % per:
            yield "first_index", self.first_index, (f"{self.task} keeps {per} demonstrations of one cloth together; "
                                                    f"expected a multiple of {per}")
        if self.camera_out is not None and not self.camera.views:
            yield "camera.views", self.camera.views, "none given; expected one or more of front, front-left, front-right, back"
        if self.camera_out is not None and Path(self.camera_out).resolve() == Path(self.out).resolve():
            yield "camera_out", self.camera_out, ("the folder of --out; expected a folder of its own (the camera "
                                                  "demos keep the mesh demos' names)")


@dataclass
class Job:
    names: list[str]  # output file names, one per demonstration of this cloth
    holes: list[int]
    task: str = ""
    split: str = ""
    cloth_index: int = 0
    replay: dict | None = None  # cloth_params, rot_z, trans of a replayed file
    floor: bool = True
    max_attempts: int = 5
    trajectories: bool = False
    render: str = "none"
    render_every: int = 10
    steps: int = 300
    out: str = ""
    camera_out: str = ""  # write the camera demos there too
    camera: CameraSpec | None = None
    camera_only: bool = False  # the mesh demos are already in `out`: write their camera demos alone


@dataclass
class JobResult:
    names: list[str]
    written: list[str] = field(default_factory=list)
    episodes: int = 0
    successes: int = 0
    exploded: int = 0
    broken: int = 0  # bag episodes that stretched, spread or tunnelled beyond the integrity bounds
    figures: list[dict] = field(default_factory=list)  # bag episodes: the integrity figures, before and after
    seconds: float = 0.0
    camera_only: bool = False


def run_job(job: Job) -> JobResult:
    """Run the expert on one cloth (every hole of a multimodal pair); save only when all its episodes succeed."""

    env = process_env(job.floor, get_task(job.task).scene)
    result = JobResult(job.names, camera_only=job.camera_only)
    if job.camera_only:
        for name in job.names:
            _write_camera_demo(env, job, name, load_demo(Path(job.out) / name))
        result.written = list(job.names)
        return result
    attempts = 1 if job.replay is not None else job.max_attempts
    for attempt in range(attempts):
        if job.replay is not None:
            cloth, rot_z, trans = job.replay["cloth_params"], job.replay["rot_z"], job.replay["trans"]
        else:
            params = episode_params(get_task(job.task), get_split(job.split), job.cloth_index, attempt)
            cloth, rot_z, trans = params.cloth_params, params.rot_z, params.trans
        episodes = []
        for hole in job.holes:
            ep = run_episode(
                env, cloth, rot_z, trans, expert_policy(hole), steps=job.steps, trajectory=job.trajectories,
                frame_every=job.render_every if job.render != "none" else 0, render=render_frame,
            )  # fmt: skip
            result.episodes += 1
            result.seconds += ep.seconds
            result.exploded += ep.exploded
            # A demonstration is labelled with the hole (or bag handle) the expert aimed at: it must pass itself.
            # A bag must also stay intact: no explosion, no tunnelling through the hook (sim/integrity.py).
            parts = ep.checks.get("holes") or ep.checks.get("handles") or []
            ok = ep.success and hole < len(parts) and all(parts[hole].values())
            integrity = ep.checks.get("integrity", {})
            intact = integrity.get("intact", True)
            if integrity:
                result.figures.append(integrity)
            result.broken += not ep.exploded and not intact
            ok = ok and intact
            result.successes += ok
            episodes.append((ep, ok))
        if all(ok for _, ok in episodes):
            for name, (ep, _) in zip(job.names, episodes):
                demo = episode_to_demo(ep, job.task)
                save_demo(Path(job.out) / name, demo)
                if job.camera_out:
                    _write_camera_demo(env, job, name, demo)
                if job.render != "none" and ep.frames:
                    save_frames(ep.frames, Path(job.out) / "renders" / Path(name).stem, job.render)
                result.written.append(name)
            break
    return result


def _write_camera_demo(env, job: Job, name: str, demo: dict) -> None:
    """The demo as the cameras see it at the start (tax3d.sim.observe): the scene reset to the demo's start."""

    env.reset(demo["deform_params"], float(demo["rot"][2]), demo["trans"])
    rng = camera_seed(job.task, job.split, demo_index(name) // get_task(job.task).demos_per_cloth)
    save_demo(Path(job.camera_out) / name, camera_demo(env, demo, job.camera, rng))


def _check_out(out: Path) -> None:
    if out.exists() and not out.is_dir():
        raise UsageError(f"--out {out}: exists and is not a folder; expected a folder for demo_N.npz files")
    try:
        out.mkdir(parents=True, exist_ok=True)
        with tempfile.NamedTemporaryFile(dir=out, prefix=".probe-"):
            pass
    except OSError as err:
        raise UsageError(f"--out {out}: cannot write there ({err.strerror}); expected a writable folder") from None


def _replay_jobs(folder: Path, args: Args) -> list[Job]:
    task = get_task(args.task)
    jobs = []
    paths = list_demos(folder)
    for path in paths if args.num is None else paths[: max(args.num, 0)]:
        demo = load_demo(path)
        if task.scene == "bag":
            cloth, hole = asdict(parse_bag_params(demo["deform_params"], where=str(path))), 0
        else:
            cloth = validate_cloth_params(demo["deform_params"], where=str(path))
            hole = demo_index(path) % cloth["num_holes"]
        rot_z, trans = float(demo["rot"][2]), np.asarray(demo["trans"], dtype=np.float64)
        # The official train split was rendered without a floor: its anchor cloud reaches below the anchor's base.
        floor = bool(demo["anchor_pc"][:, 2].min() >= trans[2] - 0.05)
        replay = {"cloth_params": cloth, "rot_z": rot_z, "trans": trans}
        jobs.append(Job([path.name], [hole], task=args.task, replay=replay, floor=floor))
    return jobs


def _generate_jobs(args: Args) -> list[Job]:
    task, split = get_task(args.task), get_split(args.split)
    num = task.sizes[split.name] if args.num is None else args.num
    per = task.demos_per_cloth
    first, end = args.first_index, args.first_index + num
    jobs = []
    for c in range(first // per, math.ceil(end / per)):
        idx = [i for i in range(c * per, (c + 1) * per) if i < end]
        jobs.append(Job([f"demo_{i}.npz" for i in idx], [i - c * per for i in idx], args.task, args.split, c))
    return jobs


def generate(args: Args, progress: bool = True) -> dict:
    """Plan, skip what is already there, run the rest; returns the summary statistics."""
    options.check(args)
    check_backend(args.backend, args.workers, args.address)
    if args.replay is not None:
        jobs = _replay_jobs(Path(args.replay), args)
    else:
        jobs = _generate_jobs(args)
        for job in jobs:
            job.floor = args.floor
    _check_out(Path(args.out))
    if args.camera_out is not None:
        _check_out(Path(args.camera_out))
    for job in jobs:
        job.out, job.max_attempts, job.trajectories = str(args.out), args.max_attempts, args.trajectories
        job.render, job.render_every, job.steps = args.render, max(1, args.render_every), args.steps
        job.camera_out, job.camera = ("", None) if args.camera_out is None else (str(args.camera_out), args.camera)
    todo = [j for j in jobs if not all(is_valid_demo(Path(args.out) / n, SIM_KEYS + ("anchors",)) for n in j.names)]
    stats = {"planned": sum(len(j.names) for j in jobs), "skipped": sum(len(j.names) for j in jobs if j not in todo)}
    if args.camera_out is not None:  # mesh demos already there whose camera demos are not: those alone
        for job in jobs:
            if job not in todo and not all(is_valid_demo(Path(args.camera_out) / n, SIM_KEYS) for n in job.names):
                job.camera_only = True
                todo.append(job)
    results = _run(todo, args, progress)
    camera_only = [r for r in results if r.camera_only]
    results = [r for r in results if not r.camera_only]
    stats.update(
        camera_written=0 if args.camera_out is None else sum(len(r.written) for r in results + camera_only),
        written=sum(len(r.written) for r in results),
        failed=[n for r in results for n in r.names if n not in r.written],
        episodes=sum(r.episodes for r in results),
        successes=sum(r.successes for r in results),
        exploded=sum(r.exploded for r in results),
        broken=sum(r.broken for r in results),
        integrity=_worst([f for r in results for f in r.figures]),
        seconds=sum(r.seconds for r in results),
    )
    stats["success_rate"] = stats["successes"] / stats["episodes"] if stats["episodes"] else float("nan")
    stats["seconds_per_episode"] = stats["seconds"] / stats["episodes"] if stats["episodes"] else float("nan")
    return stats


def _worst(figures: list[dict]) -> dict:
    """The largest stretch, spread and penetration over bag episodes, before and after release ({} for cloths)."""
    keys = ("stretch", "spread", "penetration")
    return {k: max(f[when][k] for f in figures for when in ("before", "after")) for k in keys} if figures else {}


def _run(jobs: list[Job], args: Args, progress: bool) -> list[JobResult]:
    bar = tqdm(total=len(jobs), desc="episodes", unit="cloth", disable=not progress or not jobs, file=sys.stderr)
    results = []
    # a process of its own for each cloth: its demonstrations are then the same however the jobs fall to workers
    for _, result, error in run_each(run_job, jobs, args.workers, args.backend, args.address, fresh=True):
        if error is not None:
            raise error
        results.append(result)
        bar.update()
    bar.close()
    return results
