"""Simulation speed: steps per second, seconds per episode on one worker, and the 2-worker throughput ratio.

Prints one JSON object. Targets (issue: HangProcCloth benchmark): at most 10 s per episode on one core and a
2-worker / 1-worker throughput ratio of at least 1.7; HangBag (--task hangbag): at most 35 s per episode.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from tax3d import provenance
from tax3d import kept
from tax3d.sim.cloth import SIMPLE_CLOTH
from tax3d.sim.env import SIM_STEPS_PER_ACTION
from tax3d.sim.scenes import env_class
from tax3d.sim.generate import Args, generate
from tax3d.sim.tasks import get_task


def sim_steps_per_second(task_name: str, env_steps: int = 100) -> float:
    task = get_task(task_name)
    with env_class(task.scene)() as env:
        state = env.reset(task.fixed_cloth or SIMPLE_CLOTH, 0.3, [2.0, -4.0, 0.0])
        targets = state.grippers + np.array([0.0, -1.0, 0.5])
        start = time.perf_counter()
        for _ in range(env_steps):
            env.step(targets)
        return env_steps * SIM_STEPS_PER_ACTION / (time.perf_counter() - start)


def episodes_wall(task: str, num: int, workers: int) -> tuple[float, dict]:
    with tempfile.TemporaryDirectory() as out:
        start = time.perf_counter()
        stats = generate(Args(task=task, split="unseen", num=num, out=Path(out), workers=workers, max_attempts=1),
                         progress=False)
        return time.perf_counter() - start, stats


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--task", default="hangproccloth-simple")
    parser.add_argument("--episodes", type=int, default=2, help="episodes per worker")
    parser.add_argument("--one-worker", action="store_true", help="skip the 2-worker run (a busy machine)")
    args = parser.parse_args()
    steps = sim_steps_per_second(args.task)
    wall1, stats1 = episodes_wall(args.task, args.episodes, 1)
    wall2, stats2 = (None, None) if args.one_worker else episodes_wall(args.task, 2 * args.episodes, 2)
    print(json.dumps(kept.stamp("sim-benchmark", 1, {
        "command": "python " + " ".join(sys.argv),
        "task": args.task,
        "machine": provenance.machine(),
        "date": provenance.today(),
        "sim_steps_per_second": round(steps, 1),
        "seconds_per_episode_1_worker": round(wall1 / stats1["episodes"], 2),
        "episode_seconds_in_worker": round(stats1["seconds_per_episode"], 2),
        "throughput_ratio_2_workers": None if wall2 is None
        else round((stats2["episodes"] / wall2) / (stats1["episodes"] / wall1), 3),
        "episodes": [stats1["episodes"]] + ([] if stats2 is None else [stats2["episodes"]]),
    }), indent=2))


if __name__ == "__main__":
    main()
