"""`tax3d eval`: a checkpoint predicts goals, the policy executes them in the simulator, the success check judges.

The environment runner (tax3d.eval) is separate from the policy it evaluates (tax3d.policies). OUT gets results.json
(the summary and every episode), summary.json (the summary alone: kept JSON of kind "eval", tax3d.kept) and the
report.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Annotated, Literal

from tax3d import provenance
from tax3d.checkpoint import WEIGHTS_NAME, sha256
from tax3d.errors import UsageError
from tax3d.eval.episodes import Episodes
from tax3d.eval.jobs import EvalJob, demos_from, plan_jobs, split_folder
from tax3d.eval.ledger import record_eval
from tax3d.eval.outputs import write_outputs
from tax3d.eval.runner import run_jobs
from tax3d.eval.summary import format_table, summarise
from tax3d import options
from tax3d.options import Finite, NonNegative, OutputFolder, Positive
from tax3d.parallel import check_backend
from tax3d.policies.goal import Sampling
from tax3d.policies.load import check_sampling, load_model
from tax3d.sim.observe import CameraSpec
from tax3d.sim.tasks import get_task
from tax3d.variants import display_name


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

    def conflicts(self):
        if self.observe == "camera" and not self.camera.views:
            yield "camera.views", self.camera.views, "none given; expected one or more of front, front-left, " \
                                                     "front-right, back"
        if self.goal == "model" and self.checkpoint is None:
            yield "checkpoint", "", "missing; expected a checkpoint folder (or --goal demo or mean with --data)"
        if self.goal != "model" and self.checkpoint is not None:
            yield "checkpoint", self.checkpoint, f"not used with --goal {self.goal}; expected one or the other"


def sampling_of(args: Args) -> Sampling:
    """The policy's sampling settings among the command's options."""
    return Sampling(samples=args.samples, steps=args.steps, sampler=args.sampler, max_points=args.max_points,
                    seed=args.seed, replan_every=args.replan_every)


def plan(args: Args) -> list[EvalJob]:
    """The command's episodes, one job each."""
    return plan_jobs(args, sampling_of(args))


def evaluate(args: Args, progress: bool = True, record: bool = True) -> dict:
    """Run the episodes and write the outputs; a scoring of test episodes goes in the ledger first (tax3d.eval.ledger),
    unless `record` is False (`tax3d table` writes its own line, with the row)."""
    options.check(args)
    task = get_task(args.task)
    check_backend(args.backend, args.workers, args.address)
    if args.goal == "model":
        model = load_model(args.checkpoint, args.device)  # fails early, in one line, on a bad checkpoint or device
        _check_task(model, args)
        check_sampling(model, args.steps, args.sampler)
        variant = model.config.model.variant
    else:
        variant = f"{args.goal}-goal"
    jobs = plan(args)
    sha = None if args.checkpoint is None else sha256(Path(args.checkpoint) / WEIGHTS_NAME)  # the weights it scored
    kept = Episodes(args.out, sha)
    results = run_jobs(jobs, args.workers, progress, backend=args.backend, address=args.address, kept=kept)
    splits = list(dict.fromkeys(j.split for j in jobs))
    summary = {
        "checkpoint": None if args.checkpoint is None else str(args.checkpoint), "task": args.task,
        "weights_sha256": sha,
        "variant": variant, "goal": args.goal,
        **provenance.made("tax3d.cli.eval"), "args": {k: str(v) for k, v in asdict(args).items()},
        "splits": summarise(results, splits),
        "policy_offset": list(task.policy_offset if args.policy_offset is None else args.policy_offset),
    }
    if record:
        record_eval(args, summary, lambda split: demos_from(split_folder(args.data, split), args.first_index,
                                                            args.episodes))
    write_outputs(args.out, summary, results,
                  f"{display_name(variant)} on {args.task}" if args.report else None)
    kept.remove()
    return {"summary": summary, "results": results}


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
