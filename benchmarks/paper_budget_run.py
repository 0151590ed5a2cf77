"""Train the `paper` preset on one GPU for a fixed wall time, with the cosine schedule fitted to that time.

    python benchmarks/paper_budget_run.py --train DIR --val DIR --task TASK --out runs/NAME --minutes 6 [--variant cd]
                                       [any option of `tax3d train`, e.g. --train.batch-size 32]

The paper's 500,000 steps take hours even on one GPU. This script measures how fast this machine trains the
`paper` preset (`--probes`, by default three probes of about 25 seconds: float32 with the preset's in-process
data loading, float32 with 6 data workers, bf16 with 6 data workers), then trains float32 with the fastest
loading for --minutes, with `--train.steps` set to the number of steps that fit (the learning rate warms up and
decays to 0 within the run, App. B.2) and validation on the first 10 `val` demos ten times along the way.
The run (and each probe) is stopped with SIGINT when its minutes are up, saving last/.
Writes OUT (as `tax3d train`) and OUT/budget.json: the machine, the probes' steps per second, the chosen steps
and where it stopped. With --minutes 0 it only runs the probes and prints their summary.
"""

from __future__ import annotations

import argparse
import json
import shutil
import signal
import subprocess
import sys
from pathlib import Path

import torch

from tax3d import kept, provenance
from tax3d.atomic import write_text
from tax3d.checkpoint import read_log

# the share of the wall time left for training steps (validation, start-up and the final checkpoint take the rest)
STEP_SHARE = 0.9


def train_command(args, out: Path, extra: list[str]) -> list[str]:
    return [sys.executable, "-m", "tax3d.cli", "train", "--preset", "paper", "--model.variant", args.variant,
            "--data.train", args.train, "--data.task", args.task, "--train.device", args.device, "--out", str(out),
            *args.train_options, *extra]


def steps_per_second(log: Path) -> float:
    """From log.jsonl: steps over seconds between the fifth step (or the middle one) and the last (start-up and compilation left out)."""
    records = read_log(log)
    if len(records) < 3:
        raise SystemExit(f"{log}: only {len(records)} steps logged; expected at least 3 from a probe")
    first, last = records[min(4, len(records) // 2)], records[-1]
    return (last["step"] - first["step"]) / (last["seconds"] - first["seconds"])


def run_training(command: list[str], out: Path, minutes: float) -> None:
    """Run `tax3d train`, stopped with SIGINT after `minutes` (it saves last/ at the end of that step and exits with
    130); its progress bar goes to OUT.stderr, whose end is shown if it fails."""
    errors = Path(str(out) + ".stderr")
    errors.parent.mkdir(parents=True, exist_ok=True)
    with open(errors, "w") as f:
        running = subprocess.Popen(command, stderr=f)
        try:
            code = running.wait(timeout=60 * minutes)
        except subprocess.TimeoutExpired:
            running.send_signal(signal.SIGINT)
            code = 0 if running.wait() == 130 else running.returncode
    if code != 0:
        print(errors.read_text()[-3000:], file=sys.stderr)
        raise SystemExit(f"paper_budget_run.py: {' '.join(command)} exited with {code}")
    errors.unlink()


def probe(args, precision: str, workers: int) -> float:
    out = Path(args.out + f"-probe-{precision}-w{workers}")
    shutil.rmtree(out, ignore_errors=True)
    run_training(train_command(args, out, ["--train.steps", "1000000", "--train.val-every", "1000000",
                                           "--train.precision", precision, "--train.num-workers", str(workers)]),
                 out, args.probe_minutes)
    rate = steps_per_second(out / "log.jsonl")
    shutil.rmtree(out)
    print(f"probe {precision}, {workers} data workers: {rate:.1f} steps/s", flush=True)
    return rate


def probe_name(precision: str, workers: int) -> str:
    return f"{precision}, " + (f"{workers} data workers" if workers else "in-process loading")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--train", required=True, help="training demo folder")
    parser.add_argument("--val", required=True, help="validation demo folder (its first 10 demos are used)")
    parser.add_argument("--task", required=True, help="the benchmark task of the demos")
    parser.add_argument("--out", required=True, help="output folder of the training run")
    parser.add_argument("--minutes", type=float, required=True, help="wall time of the training run (0: probes only)")
    parser.add_argument("--variant", default="cd")
    parser.add_argument("--probes", default="fp32:0,fp32:6,bf16:6",
                        help="comma-separated PRECISION:WORKERS; the training run takes the fastest fp32 one")
    parser.add_argument("--probe-minutes", type=float, default=0.4, help="wall time of each probe")
    parser.add_argument("--device", default="cuda", help="cuda, or cpu for a dry run of the script")
    args, args.train_options = parser.parse_known_args()
    if args.device == "cuda" and not torch.cuda.is_available():
        print("paper_budget_run.py: no CUDA device is available; expected a machine with a GPU", file=sys.stderr)
        return 2
    try:
        probes = [(p.split(":")[0], int(p.split(":")[1])) for p in args.probes.split(",")]
        assert all(precision in ("fp32", "bf16") and workers >= 0 for precision, workers in probes)
        assert any(precision == "fp32" for precision, _ in probes)
    except (IndexError, ValueError, AssertionError):
        print(f"paper_budget_run.py: --probes {args.probes!r}: expected comma-separated PRECISION:WORKERS "
              f"(fp32 or bf16, workers >= 0), at least one fp32", file=sys.stderr)
        return 2

    rates = {probe_spec: probe(args, *probe_spec) for probe_spec in probes}
    rate, workers = max((r, w) for (precision, w), r in rates.items() if precision == "fp32")
    summary = kept.stamp("paper-budget", 1, {
        "machine": provenance.machine(f"torch {torch.__version__}",
                                      torch.cuda.get_device_name(0) if args.device == "cuda" else "no GPU"),
        "date": provenance.today(),
        "command": " ".join(["python", "benchmarks/paper_budget_run.py", *sys.argv[1:]]),
        "probe_steps_per_second": {probe_name(*k): round(v, 2) for k, v in rates.items()},
        "paper_budget_hours_at_this_rate": round(500_000 / rate / 3600, 2),
    })
    if args.minutes <= 0:
        print(json.dumps(summary, indent=1))
        return 0
    steps = max(10, int(rate * 60 * args.minutes * STEP_SHARE))
    steps = steps // 100 * 100 if steps >= 1000 else steps
    every = max(1, steps // 10)
    extra = ["--train.steps", str(steps), "--train.val-every", str(every), "--train.val-demos", "10",
             "--data.val", args.val, "--train.num-workers", str(workers)]
    print(f"training {steps} steps, validating every {every}", flush=True)
    run_training(train_command(args, Path(args.out), extra), Path(args.out), args.minutes)
    records = read_log(Path(args.out) / "log.jsonl")
    vals = [(r["step"], r["val_rmse"]) for r in records if "val_rmse" in r]
    summary.update({
        "train_options": [*args.train_options, *extra],
        "planned_steps": steps,
        "reached_step": records[-1]["step"],
        "seconds": records[-1]["seconds"],
        "val_rmse": vals,
        "best_val_rmse": min(v for _, v in vals),
    })
    write_text(Path(args.out) / "budget.json", json.dumps(summary, indent=1) + "\n")
    print(json.dumps(summary, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
