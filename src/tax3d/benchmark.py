"""`tax3d benchmark`: generate the demonstrations, train each variant, evaluate it; resumable at every stage."""

from __future__ import annotations


import dataclasses
import json
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, Literal

from tax3d.atomic import write_text
from tax3d.errors import UsageError
from tax3d.options import NonNegative, OutputFolder, Positive

SPLITS = ("train", "unseen", "ood")


@dataclass
class Args:
    """Generate, train and evaluate a task for a list of variants; rerun the same command to continue after a stop."""

    task: str = "hangproccloth-simple"
    variants: str = "cd,cp"
    """comma-separated variants: cd, cp, cd_w, cp_w, cd_nac, cp_nac, sd, sp, rd, rp"""
    out: Annotated[Path, OutputFolder] = Path("runs/benchmark")
    """output folder: data/<split>, <variant>/train, <variant>/eval, results.md"""
    preset: Literal["cpu", "paper"] = "cpu"
    """training settings and budget; `paper` is the paper's (about 500k steps, a GPU job)"""
    steps: Annotated[int | None, Positive] = None
    """training steps per variant (default: the preset's)"""
    minutes: Annotated[float, NonNegative] = 0.0
    """training time limit per variant, in minutes (0: none)"""
    num_train: Annotated[int | None, Positive] = None
    """training demonstrations (default: the paper's size for the task)"""
    episodes: Annotated[int | None, Positive] = None
    """evaluation episodes per split (default: the paper's sizes; train: every training demonstration)"""
    samples: Annotated[int, Positive] = 1
    """goal samples per evaluation episode (coverage and precision RMSE need several)"""
    workers: Annotated[int, Positive] = 2
    """worker processes for generation and evaluation"""
    data: Path | None = None
    """existing demonstrations with one folder per split (default: OUT/data, generated here)"""
    device: str = "auto"
    """where training and evaluation's predictions run: auto (CUDA when there is one), cpu, cuda or cuda:K"""


def _generate_data(args: Args) -> Path:
    from tax3d.sim.generate import Args as GenerateArgs
    from tax3d.sim.generate import generate
    from tax3d.sim.tasks import get_task

    if args.data is not None:
        if not (args.data / "train").is_dir():
            raise UsageError(f"--data {args.data}: expected a train folder of demo_N.npz files inside it")
        return args.data
    task = get_task(args.task)
    root = args.out / "data"
    for split in SPLITS:
        num = args.num_train if split == "train" and args.num_train is not None else task.sizes[split]
        if split != "train" and args.episodes is not None:
            num = args.episodes
        print(f"[benchmark] demonstrations: {args.task} {split} ({num}) -> {root / split}", flush=True)
        stats = generate(GenerateArgs(task=args.task, split=split, num=num, out=root / split, workers=args.workers))
        if stats["failed"]:
            print(f"[benchmark] {len(stats['failed'])} {split} demos failed after every attempt; continuing without them")
    return root


def _train(args: Args, variant: str, data: Path) -> Path:
    from tax3d import config as cfg
    from tax3d import train

    out = args.out / variant / "train"
    done = out / "DONE"
    if not done.exists():
        print(f"[benchmark] training {variant} -> {out}", flush=True)
        val = data / "unseen" if (data / "unseen").is_dir() else None
        train.run(train.Args(
            out=str(out), preset=args.preset,
            model=cfg.ModelOverrides(**_only(cfg.ModelOverrides, variant=variant)),
            data=cfg.DataOverrides(**_only(cfg.DataOverrides, train=(str(data / "train"),),
                                           val=(str(val),) if val else None, task=args.task)),
            train=cfg.TrainOverrides(**_only(cfg.TrainOverrides, steps=args.steps, device=args.device,
                                             time_limit=args.minutes if args.minutes > 0 else None)),
        ))  # fmt: skip
        done.write_text("finished\n")
    return out / "best" if (out / "best").is_dir() else out / "last"


def _only(cls, **values) -> dict:
    names = {f.name for f in dataclasses.fields(cls)}
    return {k: v for k, v in values.items() if k in names and v is not None}


def run(args: Args) -> int:
    from tax3d.model.variants import variant_spec
    from tax3d.devices import pick_device
    from tax3d.evaluate import Args as EvalArgs
    from tax3d.evaluate import evaluate, format_table
    from tax3d.sim.tasks import get_task

    get_task(args.task)
    pick_device(args.device)  # a bad --device fails before any demonstration is generated
    variants = [variant_spec(v.strip()).name for v in args.variants.split(",") if v.strip()]
    if not variants:
        raise UsageError("--variants: expected at least one variant")
    data = _generate_data(args)
    tables = {}
    for variant in variants:
        checkpoint = _train(args, variant, data)
        result_file = args.out / variant / "eval" / "results.json"
        if not result_file.exists():
            print(f"[benchmark] evaluating {variant} ({checkpoint})", flush=True)
            evaluate(EvalArgs(checkpoint=checkpoint, task=args.task, splits=",".join(SPLITS), data=data,
                              episodes=args.episodes, samples=args.samples, workers=args.workers,
                              device=args.device, out=args.out / variant / "eval"))
        tables[variant] = json.loads(result_file.read_text())["summary"]["splits"]
    lines = [f"# {args.task}: {', '.join(variants)}", ""]
    for variant, table in tables.items():
        lines += [f"## {variant}", "", "```", format_table(table), "```", ""]
        print(f"{variant}\n{format_table(table)}\n")
    path = args.out / "results.md"
    write_text(path, "\n".join(lines))
    print(f"results: {path}")
    return 0
