"""Validation RMSE against wall time: configurations trained side by side for the same minutes, one thread each.

    python -m lab.studies.time_to_quality --minutes 60 --train data/unimodal/train --val data/unimodal/val \
        --run shipped "" --run x0 "--diffusion.loss x0" --out runs/ttq [--validations 12] [--val-demos 20]

Each `--run NAME OPTIONS` is a `tax3d train --preset PRESET --train.minutes M` with its own extra options, started
at the same moment as the others and pinned to a core of its own (data workers included), so that all see the
same machine and none borrows another's core. The run plans its steps to end after M
minutes and validates `--validations` times on the first `--val-demos` demos of `--val`, which training never
sees, with the checkpoint's own sampler and steps (the ones `tax3d predict` uses by default). Prints one JSON
object, also written to OUT/time_to_quality.json: per run, its options, steps per minute and every validation
(minutes, step, val_rmse: min over `--val-samples` samples, val_rmse_mean: mean over them; on multimodal
val_coverage_rmse: each cloth's goals against the samples of all its demos, appendix C).

    python -m lab.studies.time_to_quality --collect NAME RUN_DIR "COMMAND" --out runs/finals

`--threads N` gives each run N torch threads and N cores of its own instead of one: one run of two threads on both
cores of a 2-core machine is the other way to spend them than two runs of one thread side by side.

`--collect` (repeatable) trains nothing: it writes the same JSON for runs already made by `tax3d train
--train.minutes M` (each run's folder and the command that made it), such as a finalist trained alone.

The runs take the cores this program may use, one each in order: two programs started side by side (two tasks, or
one run each) must be given cores of their own, `taskset -c 0 python -m lab.studies.time_to_quality ...` beside
`taskset -c 1 ...`, or both would pin their first run to the same core.
"""

from __future__ import annotations

import argparse
import json
import os
import shlex
import subprocess
import sys
import time
from pathlib import Path

from tax3d import kept, provenance
from tax3d.atomic import write_json
from tax3d.checkpoint import read_log
from lab.studies import command_line


def train_command(args, name: str, options: str) -> list[str]:
    return [sys.executable, "-m", "tax3d.cli", "train", "--preset", args.preset, "--out", str(args.out / name),
            "--data.train", *args.train, "--data.val", *args.val, "--train.minutes", str(args.minutes),
            "--train.validations", str(args.validations), "--train.val-demos", str(args.val_demos),
            "--train.val-samples", str(args.val_samples), "--train.threads", str(args.threads), "--data.task", args.task,
            *shlex.split(options)]


def summary(out: Path, options: str, command: list[str]) -> dict:
    """One run's curve from its log.jsonl: every validation, with the mean of the training loss's mean term (`mse`)
    over the steps since the one before (train_mse: a falling train_mse beside a flat val_rmse is overfitting), and
    the plan it made (and its re-timing at the first validation, if any)."""
    records = read_log(out / "log.jsonl")
    plan = next((r["plan"] for r in records if "plan" in r), None)
    replan = next((r["replan"] for r in records if "replan" in r), None)
    curve, losses = [], []
    for r in records:
        if "mse" in r:
            losses.append(r["mse"])
        if "val_rmse" in r:
            curve.append({"minutes": round(r["seconds"] / 60, 2), "step": r["step"], "val_rmse": r["val_rmse"],
                          "val_rmse_mean": r["val_rmse_mean"],
                          **({"val_grip_error": r["val_grip_error"]} if "val_grip_error" in r else {}),
                          **({"val_coverage_rmse": r["val_coverage_rmse"]} if "val_coverage_rmse" in r else {}),
                          "train_mse": sum(losses) / len(losses) if losses else None})
            losses = []
    last = records[-1]
    config = json.loads((out / "config.json").read_text())
    return {"options": options, "command": " ".join(shlex.quote(c) for c in command), "config": config, "plan": plan,
            **({"replan": replan} if replan else {}), "steps": last["step"], "minutes": round(last["seconds"] / 60, 2),
            "steps_per_minute": round(last["step"] / (last["seconds"] / 60), 1), "curve": curve}


def collect(runs: list[list[str]], out: Path) -> int:
    """The JSON of runs already trained: each NAME RUN_DIR COMMAND; the settings come from the runs' config.json."""
    results = {}
    for name, folder, command in runs:
        if not (Path(folder) / "log.jsonl").is_file():
            print(f"time_to_quality: --collect {folder}: no log.jsonl; expected a `tax3d train` output folder",
                  file=sys.stderr)
            return 2
        results[name] = summary(Path(folder), "", shlex.split(command))
    first = next(iter(results.values()))
    config, plan = first["config"], first["plan"] or {}
    result = {"benchmark": "time_to_quality", "collected": True, "cores_per_run": 1, "minutes": plan.get("minutes"),
              "preset": "cpu", "train": config["data"]["train"], "val": config["data"]["val"],
              "val_demos": config["train"]["val_demos"], "val_samples": config["train"]["val_samples"],
              "machine": provenance.machine(), "date": provenance.today(),
              "wall_minutes": max(r["minutes"] for r in results.values()), "runs": results}
    out.mkdir(parents=True, exist_ok=True)
    print(write_json(out / "time_to_quality.json", kept.stamp("study", 1, result), indent=1))
    return 0


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--collect", nargs=3, action="append", metavar=("NAME", "RUN_DIR", "COMMAND"))
    if "--collect" in sys.argv:
        parser.add_argument("--out", type=Path, default=Path("runs/time_to_quality"))
        args = parser.parse_args()
        return collect(args.collect, args.out)
    parser.add_argument("--minutes", type=float, required=True)
    parser.add_argument("--train", nargs="+", required=True)
    parser.add_argument("--val", nargs="+", required=True)
    parser.add_argument("--run", nargs=2, action="append", metavar=("NAME", "OPTIONS"), required=True)
    parser.add_argument("--out", type=Path, default=Path("runs/time_to_quality"))
    parser.add_argument("--preset", default="cpu")
    parser.add_argument("--task", default="", help="recorded in each checkpoint's config as data.task")
    parser.add_argument("--validations", type=int, default=12)
    parser.add_argument("--val-demos", type=int, default=20)
    parser.add_argument("--val-samples", type=int, default=2)
    parser.add_argument("--threads", type=int, default=1, help="torch threads and cores of each run")
    args = parser.parse_args()
    names = [name for name, _ in args.run]
    cores = sorted(os.sched_getaffinity(0))
    wrong = [message for bad, message in (
        (len(set(names)) != len(names), f"--run: names must differ, got {names}"),
        (min(args.minutes, args.validations, args.val_demos, args.threads) <= 0,
         "--minutes, --validations, --val-demos and --threads must be positive"),
        (args.threads > len(cores), f"--threads: {args.threads} is more than the {len(cores)} core(s) this program "
                                    "may use"),
        *(((args.out / n).exists(), f"--out: {args.out / n} exists; expected a fresh folder for each run")
          for n in names)) if bad]
    if wrong:
        print(f"time_to_quality: {wrong[0]}", file=sys.stderr)
        return 2
    args.out.mkdir(parents=True, exist_ok=True)

    started = time.time()
    commands = {name: train_command(args, name, options) for name, options in args.run}
    env = {**os.environ, "OMP_NUM_THREADS": str(args.threads)}
    procs = {}
    for i, (name, command) in enumerate(commands.items()):
        log = open(args.out / f"{name}.stderr", "w")
        # cores of its own (with its data worker, if any), so that no run borrows another's core
        core = {cores[(i * args.threads + j) % len(cores)] for j in range(args.threads)}
        procs[name] = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=log, env=env,
                                       preexec_fn=lambda core=core: os.sched_setaffinity(0, core))
    failed = [name for name, proc in procs.items() if proc.wait() != 0]
    if failed:
        print(f"time_to_quality: run(s) {', '.join(failed)} failed; see {args.out}/NAME.stderr", file=sys.stderr)
        return 1
    result = {
        "benchmark": "time_to_quality", "command": command_line(__spec__.name, sys.argv[1:]),
        "cores_per_run": args.threads if len(args.run) * args.threads <= len(cores)
        else len(cores) / len(args.run), "threads_per_run": args.threads,
        "minutes": args.minutes, "preset": args.preset, "train": args.train, "val": args.val,
        "val_demos": args.val_demos, "val_samples": args.val_samples, "machine": provenance.machine(),
        "date": provenance.today(), "wall_minutes": round((time.time() - started) / 60, 1),
        "runs": {name: summary(args.out / name, options, commands[name]) for name, options in args.run},
    }
    print(write_json(args.out / "time_to_quality.json", kept.stamp("study", 1, result), indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
