"""Evaluation speed: seconds per evaluated episode (prediction and simulation apart) and the 2-worker ratio.

Prints one JSON object. Uses the shipped TAX3D-CD checkpoint unless --checkpoint is given; fresh unseen poses.
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
from tax3d.cli.demo import SHIPPED

ROOT = Path(__file__).resolve().parents[1]
from tax3d.cli.eval import Args, plan
from tax3d.eval.runner import run_jobs


def timed(args: Args, workers: int) -> tuple[float, list[dict]]:
    jobs = plan(args)
    for job in jobs:
        job.denoising = False
    start = time.perf_counter()
    results = run_jobs(jobs, workers, progress=False)
    return time.perf_counter() - start, results


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--checkpoint", type=Path, default=SHIPPED)
    parser.add_argument("--episodes", type=int, default=2, help="episodes per worker")
    parser.add_argument("--steps", type=int, default=None, help="denoising steps (default: the checkpoint's)")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as out:
        common = dict(checkpoint=args.checkpoint, splits="unseen", steps=args.steps, first_index=2000, out=Path(out))
        wall1, one = timed(Args(episodes=args.episodes, **common), 1)
        wall2, two = timed(Args(episodes=2 * args.episodes, **common), 2)
    print(json.dumps(kept.stamp("eval-benchmark", 1, {
        "command": "python " + " ".join(sys.argv),
        "checkpoint": str(args.checkpoint.resolve().relative_to(ROOT) if args.checkpoint.resolve().is_relative_to(ROOT)
                          else args.checkpoint),
        "machine": provenance.machine(),
        "date": provenance.today(),
        "seconds_per_episode_1_worker": round(wall1 / len(one), 2),
        "predict_seconds_per_episode": round(float(np.mean([r["predict_seconds"] for r in one])), 3),
        "sim_seconds_per_episode": round(float(np.mean([r["sim_seconds"] for r in one])), 2),
        "throughput_ratio_2_workers": round((len(two) / wall2) / (len(one) / wall1), 3),
        "episodes": [len(one), len(two)],
        "success": [sum(r["success"] for r in one), sum(r["success"] for r in two)],
    }), indent=2))


if __name__ == "__main__":
    main()
