"""`tax3d table`: the paper's table of one task, row by row, under one protocol; resumable at every stage.

Every row (a variant) trains on the same demonstrations with the same preset and budget, keeps the weights that
validate best on the `val` split, and is then scored once on the test episodes: `unseen` and `ood` demos from
TEST_FIRST_INDEX on, which no choice has touched. A finished row's summary is written at once (to --keep too),
and a rerun skips what is there, in OUT or in --keep: a row is never trained or scored again unless --rescore (score
again) or --retrain (train again from the start, then score) asks, and its summary counts both. Every scoring is
first appended to the ledger (tax3d.eval.ledger), which no deletion or rerun of a row shortens.
"""

from __future__ import annotations

import dataclasses
import itertools
import json
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated

from tax3d import config as cfg
from tax3d import kept, options, provenance
from tax3d.atomic import write_json, write_text
from tax3d.baselines.dp3 import config as dp3_cfg
from tax3d.checkpoint import WEIGHTS_NAME, read_log, sha256
from tax3d.cli import eval as evaluation
from tax3d.cli import train
from tax3d.cli import train_dp3 as dp3_train
from tax3d.config import PresetName, cpu_preset_of
from tax3d.data.format import is_valid_demo, list_demos, strip_trajectories
from tax3d.devices import pick_device
from tax3d.data.digest import demos_digest
from tax3d.errors import UsageError
from tax3d.eval import ledger
from tax3d.eval.summary import format_table
from tax3d.options import NonNegative, OutputFolder, Positive
from tax3d.sim import generate as gen
from tax3d.sim.tasks import get_task
from tax3d.variants import FIXED_GOALS, ROWS, table_rows

# Each attempt draws the cloth and pose of its index afresh (tax3d.sim.generate); the simulation is not bit-exact
# across machines, and three multimodal cloths of 256 failed five attempts on one machine that passed on another
DATA_ATTEMPTS = 10


@dataclass
class Args:
    """Train and score each row of a task's table; rerun the same command to continue after a stop."""

    task: str = "hangproccloth-simple"
    """hangproccloth-simple, hangproccloth-unimodal, hangproccloth-multimodal or hangbag"""
    variants: str = "cd,cp"
    """comma-separated rows: cd, cp, cd_w, cp_w, cd_nac, cp_nac, sd, sp, rd, rp, dp3 (the baseline, trained on the
    same demonstrations with their trajectories, for the same minutes; its last weights), and the fixed goals that
    bound the policy: floor (the mean goal of the train folder in the anchor frame) and ceiling (each episode's own
    demonstrated goal), scored on the same test episodes without training; `all`: every row of the task's table in
    appendix D (RD and RP on multimodal only) and both fixed goals"""
    out: Annotated[Path, OutputFolder] = Path("runs/table")
    """output folder: data/<split>, <variant>/train, <variant>/eval, results.md"""
    preset: PresetName | None = None
    """training settings of every row (default: the task's CPU recipe, cpu-multimodal on multimodal, else cpu)"""
    steps: Annotated[int | None, Positive] = None
    """training steps per row (default: the preset's; not with --minutes)"""
    minutes: Annotated[float, NonNegative] = 0.0
    """the wall-time budget of every row: each plans its steps to end after this many minutes (0: use steps)"""
    num_train: Annotated[int | None, Positive] = None
    """training demonstrations (default: the paper's size for the task); the first NUM of the train folder"""
    num_val: Annotated[int, Positive] = 40
    """val demonstrations generated (the weights are chosen on the preset's first train.val_demos of them)"""
    episodes: Annotated[int, Positive] = 40
    """test episodes per split (unseen and ood), the paper's 40"""
    first_index: Annotated[int, NonNegative] = 100
    """index of the first test episode of unseen and ood (demo_FIRST.npz ...)"""
    samples: Annotated[int, Positive] = 5
    """goal samples per test episode (the policy executes the first; coverage and precision RMSE use all)"""
    workers: Annotated[int, Positive] = 2
    """worker processes for generation and evaluation"""
    data: Path | None = None
    """demonstrations with one folder per split, completed here where demos are missing (default: OUT/data)"""
    keep: Path | None = None
    """also write each scored row's summary here, as VARIANT.json (a folder of the repository, say); a row kept
    here is not trained or scored again, even where OUT is gone"""
    rescore: bool = False
    """score rows on the test episodes again even where they have been (the count is kept in the summary); the
    row's trained weights must still be in OUT"""
    retrain: bool = False
    """train the rows again from the start (after a fix to their training) and score them again: the weights they
    were scored with move to OUT/VARIANT/train.replaced-K, and the count of scorings goes on; a rerun after a kill
    resumes the new training"""
    data_only: bool = False
    """only make the rows' demonstrations (train, val, the test episodes; train-traj for dp3), then stop: to make
    them once with more --workers than the rows are scored with"""
    device: str = "auto"
    """where training and evaluation's predictions run: auto (CUDA when there is one), cpu, cuda or cuda:K"""

    def conflicts(self):
        if self.steps is not None and self.minutes > 0:
            yield "steps", self.steps, f"not with --minutes {self.minutes:g}; expected one budget"
        variants = _rows(self)
        unknown = [v for v in variants if v not in ROWS]
        if unknown:
            yield "variants", "", f"unknown row {unknown[0]!r}; expected some of {', '.join(ROWS)}, or all"
        elif not variants:
            yield "variants", "", "expected at least one variant"


def preset_of(args: Args) -> str:
    return args.preset or cpu_preset_of(args.task)


def _generate_data(args: Args) -> Path:
    """train (NUM_TRAIN), val (NUM_VAL), and the test episodes of unseen and ood; only what is missing is made. With
    DP3 among the rows, train-traj comes first and train takes its demos without their trajectories: one simulation
    of each training demo, and DP3 and TAX3D train on the very same demonstrations."""
    task = get_task(args.task)
    root = args.out / "data" if args.data is None else args.data
    num_train = args.num_train or task.sizes["train"]
    plan = [("train", "train", 0, num_train), ("val", "val", 0, args.num_val),
            ("unseen", "unseen", args.first_index, args.episodes), ("ood", "ood", args.first_index, args.episodes)]
    if "dp3" in _rows(args):
        plan.insert(0, ("train", "train-traj", 0, num_train))
    for split, folder, first, num in plan:
        print(f"[table] demonstrations: {args.task} {split} demo_{first}-{first + num - 1} -> {root / folder}",
              flush=True)
        stats = gen.generate(gen.Args(task=args.task, split=split, first_index=first, num=num, out=root / folder,
                                      workers=args.workers, trajectories=folder == "train-traj",
                                      max_attempts=DATA_ATTEMPTS), progress=False)
        if stats["failed"]:
            raise UsageError(f"--data {root / folder}: {len(stats['failed'])} demos failed after every attempt "
                             f"({' '.join(stats['failed'][:3])}); expected every index of the table")
        if folder == "train-traj":  # train: the same files (generate validated them), trajectories left out
            (root / "train").mkdir(parents=True, exist_ok=True)
            for name in (f"demo_{i}.npz" for i in range(first, first + num)):
                if (root / folder / name).is_file() and not is_valid_demo(root / "train" / name):
                    strip_trajectories(root / folder / name, root / "train" / name)
    return root


def _train_files(folder: Path, num: int) -> tuple[str, ...]:
    """The train folder itself when it holds exactly NUM demos, else its first NUM files."""
    files = list_demos(folder)
    if len(files) < num:
        raise UsageError(f"--num-train {num}: {folder} holds {len(files)} demos; expected at least {num}")
    return (str(folder),) if len(files) == num else tuple(str(p) for p in files[:num])


def _train(args: Args, variant: str, data: Path) -> Path:
    out = args.out / variant / "train"
    num = args.num_train or get_task(args.task).sizes["train"]
    if variant == "dp3":
        return _train_dp3(args, out, _train_files(data / "train-traj", num))
    if not (out / "DONE").exists():
        print(f"[table] training {variant} -> {out}", flush=True)
        train.run(train_args(args, variant, out, _train_files(data / "train", num), data / "val"))
        write_text(out / "DONE", "finished\n")
    return out / "best" if (out / "best").is_dir() else out / "last"


def train_args(args: Args, variant: str, out: Path, files: tuple[str, ...], val: Path):
    """The `tax3d train` a row runs: the preset, the variant, the demonstrations and the budget, nothing else."""
    return train.Args(
        out=str(out), preset=preset_of(args),
        model=cfg.ModelOverrides(**_only(cfg.ModelOverrides, variant=variant)),
        data=cfg.DataOverrides(**_only(cfg.DataOverrides, train=files, val=(str(val),), task=args.task)),
        train=cfg.TrainOverrides(**_only(cfg.TrainOverrides, steps=args.steps, device=args.device,
                                         minutes=args.minutes if args.minutes > 0 else None)),
    )  # fmt: skip


def _train_dp3(args: Args, out: Path, files: tuple[str, ...]) -> Path:
    """DP3 on the same demonstrations (with trajectories) for the same minutes; it validates nothing: last/."""
    if not (out / "DONE").exists():
        print(f"[table] training dp3 -> {out}", flush=True)
        dp3_train.run(dp3_train.Args(
            out=str(out), preset="paper" if args.preset == "paper" else "cpu", device=args.device,
            data=dp3_cfg.DataOverrides(**_only(dp3_cfg.DataOverrides, train=files, task=args.task)),
            train=dp3_cfg.TrainOverrides(**_only(dp3_cfg.TrainOverrides, steps=args.steps,
                                                 minutes=args.minutes if args.minutes > 0 else None)),
        ))  # fmt: skip
        write_text(out / "DONE", "finished\n")
    return out / "last"


def _only(cls, **values) -> dict:
    names = {f.name for f in dataclasses.fields(cls)}
    return {k: v for k, v in values.items() if k in names and v is not None}


def _data_digests(args: Args, data: Path) -> dict:
    """The digest of each split a row used: its training demos, the val demos, the test episodes."""
    num = args.num_train or get_task(args.task).sizes["train"]
    test = [f"demo_{i}.npz" for i in range(args.first_index, args.first_index + args.episodes)]
    return {"train": demos_digest(list_demos(data / "train")[:num]),
            "val": demos_digest(list_demos(data / "val")[:args.num_val]),
            **{split: demos_digest([data / split / name for name in test]) for split in ("unseen", "ood")}}


def _kept(args: Args, variant: str) -> dict | None:
    """The row's summary in --keep, where OUT has lost it (a fresh machine, OUT deleted): it counts as scored."""
    path = None if args.keep is None else args.keep / f"{variant}.json"
    if path is None or not path.is_file():
        return None
    row = json.loads(path.read_text())
    if (row.get("task"), row.get("num_train")) != (args.task, args.num_train):
        raise UsageError(f"--keep {args.keep}: {path.name} holds the row of {row.get('task')} with --num-train "
                         f"{row.get('num_train')}; expected {args.task} with --num-train {args.num_train}, or "
                         f"another --keep folder")
    return row


def _scored(args: Args, variant: str) -> dict | None:
    """The row's summary where it has been scored: in OUT, else in --keep (OUT gone)."""
    path = args.out / variant / "row.json"
    return json.loads(path.read_text()) if path.is_file() else _kept(args, variant)


def _score(args: Args, variant: str, checkpoint: Path | None, data: Path) -> dict:
    """The row's summary: scored on the test episodes now, or read back when it has been (unless --rescore)."""
    row = _scored(args, variant)
    if row is not None and not (args.rescore or args.retrain):
        return row
    print(f"[table] scoring {variant} ({checkpoint or 'a fixed goal'}) on the test episodes", flush=True)
    scoring = evaluation.Args(checkpoint=checkpoint, goal=FIXED_GOALS.get(variant, "model"), task=args.task,
                              splits="unseen,ood", data=data, first_index=args.first_index, episodes=args.episodes,
                              samples=args.samples, workers=args.workers, device=args.device,
                              out=args.out / variant / "eval")
    summary = evaluation.evaluate(scoring, progress=False, record=False)["summary"]
    digests = _data_digests(args, data)
    ledger.append(ledger.default_path(), ledger.scoring(args.task, args.num_train, variant, summary, digests,
                                                        args.first_index, command()))
    run = args.out / variant / "train"
    validations = [] if checkpoint is None else [{"step": r["step"], "val_rmse": r["val_rmse"]}
                                                 for r in read_log(run / "log.jsonl") if "val_rmse" in r]
    config = None if checkpoint is None else json.loads((checkpoint / "config.json").read_text())
    preset = (None if checkpoint is None else preset_of(args) if variant != "dp3"
              else "paper" if args.preset == "paper" else "cpu")
    row = kept.stamp("table-row", 1, {
        "task": args.task, "variant": variant, "preset": preset, "minutes": args.minutes, "num_train": args.num_train,
        "weights": None if checkpoint is None else checkpoint.name,
        "weights_chosen_on": ("nothing: a fixed goal" if checkpoint is None
                              else "val" if checkpoint.name == "best" else "last step"),
        "weights_sha256": summary["weights_sha256"], "validations": validations, "config": config,
        "test": {"first_index": args.first_index, "episodes": args.episodes, "samples": args.samples,
                 "scorings": (row or {}).get("test", {}).get("scorings", 0) + 1},
        "trainings": (row or {}).get("trainings", 1) + (row is not None and args.retrain),
        "splits": summary["splits"], "data_sha256": digests,
        "command": command(), "machine": summary["machine"], "date": summary["date"]})
    write_json(args.out / variant / "row.json", row)
    if args.keep is not None:
        write_json(args.keep / f"{variant}.json", row)
    return row


def _trained_weights_sha(row: dict, run: Path) -> str | None:
    """The sha256 of the weights file in `run` that the row names (best/ or last/), None where there is none."""
    weights = run / row["weights"] / WEIGHTS_NAME
    return sha256(weights) if weights.is_file() else None


def _retraining(args: Args, variant: str) -> bool:
    """Whether OUT holds a training begun by --retrain whose weights the row has not yet been scored with."""
    row, run = _scored(args, variant), args.out / variant / "train"
    if row is None or row.get("weights") is None or not any(run.parent.glob("train.replaced-*")):
        return False
    return _trained_weights_sha(row, run) != row["weights_sha256"]


def _set_aside(args: Args, variant: str) -> None:
    """--retrain: move the finished training whose weights the row was scored with to train.replaced-K, so that the
    row trains from the start; a training begun since (unfinished, or not yet scored) stays and goes on."""
    row, run = _scored(args, variant), args.out / variant / "train"
    if row is None or not (run / "DONE").is_file():
        return
    if _trained_weights_sha(row, run) not in (None, row["weights_sha256"]):
        return
    k = next(k for k in itertools.count(1) if not (run.parent / f"train.replaced-{k}").exists())
    run.rename(run.parent / f"train.replaced-{k}")
    print(f"[table] {variant}: the weights scored before are now in {run.parent / f'train.replaced-{k}'}; "
          f"training again", flush=True)


def command() -> str:
    """The command line of this table run, as a page shows it."""
    return provenance.command("tax3d.cli.table")


def _rows(args: Args) -> list[str]:
    """--variants as row names (`CD-W` is cd_w), `all` expanded to the task's table."""
    variants = [v.strip().lower().replace("-", "_") for v in args.variants.split(",") if v.strip()]
    return list(table_rows(args.task)) if variants == ["all"] else variants


def _check(args: Args) -> list[str]:
    get_task(args.task)
    options.check(args)
    pick_device(args.device)  # a bad --device fails before any demonstration is generated
    variants = _rows(args)
    if args.keep is not None:
        args.keep.mkdir(parents=True, exist_ok=True)
        for variant in variants:
            _kept(args, variant)  # a kept row of another task or size fails here, before any long work
    for variant in variants if not (args.rescore or args.retrain) else ():
        if _retraining(args, variant):
            raise UsageError(f"--variants {variant}: {args.out / variant / 'train'} holds a training begun by "
                             f"--retrain and not yet scored; expected --retrain again, to finish it")
    for variant in variants if args.rescore and not args.retrain else ():
        run = args.out / variant / "train"
        if variant not in FIXED_GOALS and _scored(args, variant) is not None and not (run / "DONE").is_file():
            raise UsageError(f"--rescore: the weights {variant} was scored with are not in {run}; expected its "
                             f"finished training there (training it again would score other weights)")
    return variants


def run(args: Args) -> int:
    variants = _check(args)
    data = _generate_data(args)
    if args.data_only:
        return 0
    tables = {}
    for variant in variants:
        scored = None if args.rescore or args.retrain else _scored(args, variant)
        if scored is not None:
            print(f"[table] {variant}: scored before, not trained or scored again (--rescore to score it)",
                  flush=True)
            if args.keep is not None and _kept(args, variant) is None:  # scored in OUT, stopped before its copy
                write_json(args.keep / f"{variant}.json", scored)
            tables[variant] = scored["splits"]
            continue
        if args.retrain and variant not in FIXED_GOALS:
            _set_aside(args, variant)
        checkpoint = None if variant in FIXED_GOALS else _train(args, variant, data)
        tables[variant] = _score(args, variant, checkpoint, data)["splits"]
    lines = [f"# {args.task}: {', '.join(variants)}", ""]
    for variant, table in tables.items():
        lines += [f"## {variant}", "", "```", format_table(table), "```", ""]
        print(f"{variant}\n{format_table(table)}\n")
    path = args.out / "results.md"
    args.out.mkdir(parents=True, exist_ok=True)  # every row may have been kept elsewhere
    write_text(path, "\n".join(lines))
    print(f"results: {path}")
    return 0
