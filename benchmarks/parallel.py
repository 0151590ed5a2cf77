"""Demonstration-generation throughput: Ray tasks against the local process pool, same workers, same seeds.

    python benchmarks/parallel.py [--demos 4] [--workers 2] [--task hangproccloth-simple]

Prints one JSON object: seconds and demos per second for each backend (Ray's start-up and shut-down included,
as a user of `tax3d generate --backend ray` meets them), their ratio, and whether both wrote identical demos.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from tax3d import provenance
from tax3d import kept
from tax3d.data.format import list_demos, load_demo
from tax3d.sim.generate import Args, generate


def timed_generate(task: str, demos: int, workers: int, backend: str, out: Path) -> float:
    start = time.perf_counter()
    generate(Args(task=task, split="train", num=demos, out=out, workers=workers, backend=backend), progress=False)
    return time.perf_counter() - start


def same_demos(a: Path, b: Path) -> bool:
    left, right = list_demos(a), list_demos(b)
    if [p.name for p in left] != [p.name for p in right]:
        return False
    keys = ("action_pc", "anchor_pc", "flow", "rot", "trans")
    return all(np.array_equal(load_demo(p)[k], load_demo(q)[k]) for p, q in zip(left, right) for k in keys)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--task", default="hangproccloth-simple")
    parser.add_argument("--demos", type=int, default=4)
    parser.add_argument("--workers", type=int, default=2)
    args = parser.parse_args()
    if importlib.util.find_spec("ray") is None:
        print("error: Ray is not installed; expected `pip install 'tax3d[ray]'`", file=sys.stderr)
        return 2
    with tempfile.TemporaryDirectory() as tmp:
        local = timed_generate(args.task, args.demos, args.workers, "local", Path(tmp) / "local")
        ray = timed_generate(args.task, args.demos, args.workers, "ray", Path(tmp) / "ray")
        identical = same_demos(Path(tmp) / "local", Path(tmp) / "ray")
    print(json.dumps(kept.stamp("parallel-benchmark", 1, {
        "command": "python " + " ".join(sys.argv),
        "machine": provenance.machine(),
        "date": provenance.today(), "task": args.task, "demos": args.demos, "workers": args.workers,
        "local_seconds": local, "ray_seconds": ray,
        "local_demos_per_second": args.demos / local, "ray_demos_per_second": args.demos / ray,
        "throughput_ratio_ray_vs_local": local / ray, "identical_demos": identical,
    }), indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
