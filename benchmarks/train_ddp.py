"""Training-step time of the `cpu` preset in one process against two under torchrun (gloo), on this machine.

    python benchmarks/train_ddp.py [--steps 30] [--warmup 5] [--rounds 2] [--demos 4]

Prints one JSON object. Each run is a real `tax3d train` on synthetic demonstrations written to a temporary
folder, with the preset's global batch (16): one process with 1 thread (the preset's), one process with 2
threads, and `torchrun --nproc_per_node 2` with 1 thread each (8 samples per process). A step's time is read
from the run's log.jsonl (seconds between consecutive steps, after `warmup` steps and before the last, which
writes a checkpoint); a run's step time is the median of those. The three runs are repeated `rounds` times,
interleaved, and the fastest round of each counts (the least disturbed by other processes on a shared machine;
the load averages recorded say how much other work there was).
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
import torch

from tax3d.data.format import save_demo
from tax3d import kept
from tax3d.checkpoint import read_log

ROOT = Path(__file__).resolve().parents[1]
LAUNCH_ENV = ("WORLD_SIZE", "RANK", "LOCAL_RANK", "LOCAL_WORLD_SIZE", "MASTER_ADDR", "MASTER_PORT")


def synthetic_demo(seed: int, n: int = 400, m: int = 400) -> dict:
    """A cloth-sized scene: a flat action cloud above an anchor, its goal moved next to the anchor."""
    rng = np.random.default_rng(seed)
    action = rng.normal(size=(n, 3)) * [2.0, 0.1, 2.0] + [0.0, 5.0, 8.0]
    anchor = rng.normal(size=(m, 3)) * [0.5, 0.5, 2.0] + [4.0, -6.0, 3.0]
    goal = action + [4.5, -11.5, 0.0] + rng.normal(size=(n, 3)) * 0.05
    return {
        "action_pc": action, "action_seg": np.ones(n), "anchor_pc": anchor,
        "anchor_seg": np.zeros(m, dtype=np.int32), "flow": goal - action, "speed_factor": np.array(1.0),
        "rot": np.zeros(3), "trans": np.zeros(3),
        "deform_params": {"num_holes": 1, "node_density": 25, "w": 1.0, "h": 1.0,
                          "holes": [{"x0": 8, "x1": 16, "y0": 9, "y1": 13}]},
        "anchors": {0: {"pos": np.zeros(3), "vertices": [0]}},
    }


def write_demos(folder: Path, count: int) -> None:
    folder.mkdir(parents=True)
    for i in range(count):
        save_demo(folder / f"demo_{i}.npz", synthetic_demo(i))


def step_seconds(log: Path, warmup: int) -> list[float]:
    seconds = {r["step"]: r["seconds"] for r in read_log(log)}
    return [seconds[s] - seconds[s - 1] for s in range(warmup + 1, max(seconds))]


def run(name: str, launcher: list[str], train_args: list[str], out: Path, warmup: int) -> dict:
    command = [*launcher, "-m", "tax3d.cli", "train", *train_args, "--out", str(out / name)]
    env = {k: v for k, v in os.environ.items() if k not in LAUNCH_ENV}
    env["OMP_NUM_THREADS"] = "1"  # torchrun's own default per process; --train.threads sets torch's threads
    load = os.getloadavg()[0]
    done = subprocess.run(command, cwd=ROOT, env=env, capture_output=True, text=True)
    if done.returncode != 0:
        sys.exit(f"{name} failed ({done.returncode}):\n{done.stderr[-3000:]}")
    seconds = step_seconds(out / name / "log.jsonl", warmup)
    return {"command": " ".join(["python", *command[1:]]), "step_s": round(float(np.median(seconds)), 4),
            "step_s_mean": round(float(np.mean(seconds)), 4), "timed_steps": len(seconds),
            "load_average_before": round(load, 2)}


def fastest(rounds: list[dict]) -> dict:
    best = min(rounds, key=lambda r: r["step_s"])
    return {**best, "step_s_rounds": [r["step_s"] for r in rounds]}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=30)
    parser.add_argument("--warmup", type=int, default=5)
    parser.add_argument("--rounds", type=int, default=2)
    parser.add_argument("--demos", type=int, default=4)
    args = parser.parse_args()
    if args.steps < args.warmup + 3:
        parser.error(f"--steps {args.steps}: expected at least --warmup + 3 = {args.warmup + 3}")

    python = [sys.executable]
    torchrun = [sys.executable, "-m", "torch.distributed.run", "--standalone", "--nproc_per_node", "2"]
    with tempfile.TemporaryDirectory(prefix="train_ddp.") as tmp:
        tmp = Path(tmp)
        write_demos(tmp / "demos", args.demos)
        train_args = ["--preset", "cpu", "--data.train", str(tmp / "demos"), "--train.steps", str(args.steps),
                      "--train.val_every", str(args.steps)]
        setups = {
            "1_process_1_thread": (python, train_args),
            "1_process_2_threads": (python, [*train_args, "--train.threads", "2"]),
            "2_processes_1_thread_each": (torchrun, train_args),
        }
        rounds = {name: [] for name in setups}
        for i in range(args.rounds):
            for name, (launcher, extra) in setups.items():
                rounds[name].append(run(f"{name}.{i}", launcher, extra, tmp, args.warmup))
    runs = {name: fastest(results) for name, results in rounds.items()}
    one, two = runs["1_process_1_thread"]["step_s"], runs["2_processes_1_thread_each"]["step_s"]
    result = {
        "benchmark": "train_ddp",
        "date": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
        "command": " ".join(["python", *sys.argv]),
        "machine": {"platform": platform.platform(), "processor": platform.processor() or platform.machine(),
                    "cpus": os.cpu_count(), "torch": torch.__version__, "python": platform.python_version(),
                    "load_average_after": [round(x, 2) for x in os.getloadavg()]},
        "preset": "cpu", "global_batch": 16, "steps": args.steps, "warmup": args.warmup, "rounds": args.rounds,
        "runs": runs,
        "speedup_2_processes_vs_1": round(one / two, 3),
        "speedup_2_processes_vs_1_process_2_threads": round(runs["1_process_2_threads"]["step_s"] / two, 3),
    }
    print(json.dumps(kept.stamp("train-ddp-benchmark", 1, result), indent=2))


if __name__ == "__main__":
    main()
