"""Validation curves at the paper's demonstration count: TAX3D-CD arms trained side by side, one core each, for
as long as it takes, resumed from each arm's last/ across calls.

    python -m lab.studies.paper_count --task hangproccloth-unimodal --train data/unimodal/train --num-train 64 \
        --val data/unimodal/val --out runs/paper-count/unimodal --hours 2.5 \
        --arm cpu "" --arm scene "--data.rotate-scene True" \
        --keep docs/results/paper-count/unimodal-cpu-scene.json

Each `--arm NAME OPTIONS` is `tax3d train --preset PRESET --model.variant cd` on the first NUM_TRAIN demos of
--train, with the paper's schedule (`--steps`, 500,000 at batch 16: 8M samples, App. B.2) and the arm's own options,
validated every `--val-every` steps on the first `--val-demos` demos of --val; the weights of every `--keep-every`
steps stay in OUT/NAME/steps/STEP for scoring the policy later. Arms start together, each pinned to a core of its own
(its data worker too). After `--hours` each gets SIGINT, saves last/ and stops; the same command resumes every arm
where it stopped. The arms of one call share the machine's load: compare them with each other, not across calls.

`--keep FILE` writes the curves (also every few minutes while the arms train, and with `--collect` alone, which
trains nothing): kept JSON of kind "paper-count", per arm its command, configuration, and at each validation the step,
samples seen, training hours on its core, val_rmse (min over --val-samples samples), val_rmse_mean (one sample, as
the policy acts) and the mean training loss since the validation before; with the data digests of both folders.
"""

from __future__ import annotations

import argparse
import json
import os
import shlex
import signal
import subprocess
import sys
import time
from pathlib import Path

from tax3d import kept, provenance
from tax3d.atomic import write_json
from tax3d.checkpoint import read_log
from tax3d.data.format import list_demos
from tax3d.data.digest import demos_digest
from lab.studies import command_line

WRITE_EVERY = 300  # seconds between two writes of --keep while the arms train
OPTIONAL = ("val_grip_error", "val_coverage_rmse", "val_precision_rmse")  # logged where the demos allow


def train_files(args) -> list[Path]:
    files = list_demos(args.train)
    if len(files) < args.num_train:
        raise SystemExit(f"paper_count: --train {args.train} holds {len(files)} demos; expected at least "
                         f"--num-train {args.num_train}")
    return files[:args.num_train]


def train_command(args, name: str, options: str) -> list[str]:
    """The arm's `tax3d train` command (the folder itself where it holds exactly NUM_TRAIN demos)."""
    files, every = train_files(args), list_demos(args.train)
    train = [str(args.train)] if len(every) == len(files) else [str(f) for f in files]
    return ["tax3d", "train", "--preset", args.preset, "--model.variant", "cd", "--out", str(args.out / name),
            "--data.train", *train, "--data.val", str(args.val), "--data.task", args.task,
            "--train.steps", str(args.steps), "--train.val-every", str(args.val_every),
            "--train.keep-every", str(args.keep_every), "--train.val-demos", str(args.val_demos),
            "--train.val-samples", str(args.val_samples), "--train.threads", "1", *shlex.split(options)]


def curve(folder: Path) -> dict:
    """One arm's validations from its log.jsonl, with the mean training loss (`mse`) since the one before."""
    records = read_log(folder / "log.jsonl") if (folder / "log.jsonl").is_file() else []
    config = json.loads((folder / "config.json").read_text()) if (folder / "config.json").is_file() else None
    batch = config["train"]["batch_size"] if config else 0
    points, losses = [], []
    for r in records:
        if "mse" in r:
            losses.append(r["mse"])
        if "val_rmse" in r:
            points.append({"step": r["step"], "samples": r["step"] * batch, "hours": round(r["seconds"] / 3600, 3),
                           "val_rmse": r["val_rmse"], "val_rmse_mean": r["val_rmse_mean"],
                           **{k: r[k] for k in OPTIONAL if k in r},
                           "train_mse": sum(losses) / len(losses) if losses else None})
            losses = []
    steps = sorted(int(p.name) for p in (folder / "steps").iterdir()) if (folder / "steps").is_dir() else []
    last = records[-1] if records else {"step": 0, "seconds": 0}
    return {"config": config, "steps": last["step"], "hours": round(last["seconds"] / 3600, 3),
            "samples_per_hour": round(last["step"] * batch / (last["seconds"] / 3600)) if last["seconds"] else None,
            "kept_steps": steps, "curve": points}


def without_hours(argv: list[str]) -> list[str]:
    """The command line less `--hours H` and `--collect`, which only say when this call stops and whether it trains:
    every call resumes the same arms."""
    out = [a for a in argv if a != "--collect"]
    while "--hours" in out:
        at = out.index("--hours")
        del out[at:at + 2]
    return [a for a in out if not a.startswith("--hours=")]


def write_keep(args, commands: dict) -> None:
    arms = {name: {"options": options, "command": shlex.join(commands[name]), **curve(args.out / name)}
            for name, options in args.arm}
    result = {"study": "paper_count", "task": args.task, "num_train": args.num_train, "preset": args.preset,
              "command": command_line(__spec__.name, without_hours(sys.argv[1:])),
              "train": str(args.train), "val": str(args.val), "val_demos": args.val_demos,
              "val_samples": args.val_samples, "digests": args.digests, "machine": provenance.machine(),
              "date": provenance.today(), "cores_per_arm": 1, "arms": arms}
    args.keep.parent.mkdir(parents=True, exist_ok=True)
    write_json(args.keep, kept.stamp("paper-count", 1, result), indent=1)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--task", required=True)
    parser.add_argument("--train", type=Path, required=True)
    parser.add_argument("--num-train", type=int, default=64)
    parser.add_argument("--val", type=Path, required=True)
    parser.add_argument("--arm", nargs=2, action="append", metavar=("NAME", "OPTIONS"), required=True)
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--keep", type=Path)
    parser.add_argument("--preset", default="cpu")
    parser.add_argument("--hours", type=float, default=0.0, help="stop the arms after this long (0: at their end)")
    parser.add_argument("--steps", type=int, default=500_000)
    parser.add_argument("--val-every", type=int, default=2500)
    parser.add_argument("--keep-every", type=int, default=25_000)
    parser.add_argument("--val-demos", type=int, default=20)
    parser.add_argument("--val-samples", type=int, default=2)
    parser.add_argument("--collect", action="store_true", help="write --keep from the arms' logs; train nothing")
    args = parser.parse_args()
    names = [name for name, _ in args.arm]
    cores = sorted(os.sched_getaffinity(0))
    wrong = [message for bad, message in (
        (len(set(names)) != len(names), f"--arm: names must differ, got {names}"),
        (len(names) > len(cores), f"--arm: {len(names)} arms need a core each; this program may use {len(cores)}"),
        (min(args.num_train, args.steps, args.val_every, args.keep_every, args.val_demos) <= 0,
         "--num-train, --steps, --val-every, --keep-every and --val-demos must be positive"),
        (args.collect and args.keep is None, "--collect needs --keep"),
        (not args.val.is_dir(), f"--val {args.val}: no such folder")) if bad]
    if wrong:
        print(f"paper_count: {wrong[0]}", file=sys.stderr)
        return 2
    commands = {name: train_command(args, name, options) for name, options in args.arm}
    args.digests = {"train": demos_digest(train_files(args)),
                    "val": demos_digest(list_demos(args.val)[:args.val_demos])}
    if args.collect:
        write_keep(args, commands)
        return 0

    args.out.mkdir(parents=True, exist_ok=True)
    env = {**os.environ, "OMP_NUM_THREADS": "1"}
    procs = {}
    for core, (name, command) in zip(cores, commands.items()):
        log = open(args.out / f"{name}.stderr", "a")
        procs[name] = subprocess.Popen([sys.executable, "-m", "tax3d.cli", *command[1:]], stdout=subprocess.DEVNULL, stderr=log, env=env,
                                       preexec_fn=lambda core=core: os.sched_setaffinity(0, {core}))
    started = last_write = time.time()
    while any(p.poll() is None for p in procs.values()):
        time.sleep(10)
        if args.hours and time.time() - started > args.hours * 3600:
            for p in procs.values():
                if p.poll() is None:
                    p.send_signal(signal.SIGINT)  # saves last/ after this step
            for p in procs.values():
                p.wait()
        if args.keep and time.time() - last_write > WRITE_EVERY:
            write_keep(args, commands)
            last_write = time.time()
    if args.keep:
        write_keep(args, commands)
    failed = [name for name, p in procs.items() if p.returncode not in (0, 130)]
    if failed:
        print(f"paper_count: arm(s) {', '.join(failed)} failed; see {args.out}/NAME.stderr", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
