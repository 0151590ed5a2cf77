"""Farthest point sampling on the CPU: the numpy loop against the torch loop, per cloud and per training sample.

    python benchmarks/fps.py [--rounds 7] [--threads 1]

Prints one JSON object. A training sample of the `paper` preset draws 512 of a cloth's ~550-650 action points and
512 of a hanger's ~1,300 anchor points with FPS (`tax3d.data.dataset.make_sample`); on a CPU those two calls were
most of a sample's cost, and the samples bound the training rate on a GPU (docs/scaling.md). The clouds are
synthetic (a wavy 25 x 25 sheet and a 1,300-point rod frame) so that no data is needed; each round times both
loops on the same clouds, and the figures are the medians over rounds.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time

import torch

from tax3d import geometry, provenance
from tax3d.data.dataset import make_sample


def clouds(seed: int = 0) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """A cloth-like action sheet (625 points), its goal (the sheet moved), and an anchor of 1,300 points."""
    gen = torch.Generator().manual_seed(seed)
    u, v = torch.meshgrid(torch.linspace(0, 0.4, 25), torch.linspace(0, 0.4, 25), indexing="ij")
    action = torch.stack([u, v, 0.02 * torch.sin(12 * u) * torch.cos(9 * v)], -1).reshape(-1, 3)
    action = action + 1e-3 * torch.randn(action.shape, generator=gen)
    t = torch.rand(1300, generator=gen)
    anchor = torch.stack([0.3 * torch.cos(6.28 * t), 0.05 * torch.randn(1300, generator=gen), 0.5 + 0.2 * t], -1)
    return action.double(), anchor.double(), (action + torch.tensor([0.1, 0.0, 0.3])).double()


def time_call(fn, repeats: int) -> float:
    start = time.perf_counter()
    for _ in range(repeats):
        fn()
    return (time.perf_counter() - start) / repeats


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=7)
    parser.add_argument("--repeats", type=int, default=10, help="calls per timing")
    parser.add_argument("--threads", type=int, default=1, help="torch threads (a data worker's: 1)")
    args = parser.parse_args()
    torch.set_num_threads(args.threads)
    action, anchor, goal = clouds()
    loops = {"torch": geometry.fps_loop_torch, "numpy": geometry.fps_loop_numpy}
    default = geometry.fps_loop_numpy
    same = True
    per_cloud = {name: [] for name in loops}
    per_sample = {name: [] for name in loops}
    for r in range(args.rounds):
        for name, loop in loops.items():
            pts = (anchor - anchor.mean(0)).float()[None]
            far = torch.tensor([r * 37 % len(anchor)])
            per_cloud[name].append(time_call(lambda: loop(pts, 512, far), args.repeats))
            geometry.fps_loop_numpy = loop  # what farthest_point_sample calls for CPU tensors
            try:
                per_sample[name].append(time_call(
                    lambda: make_sample(action, anchor, goal, "cd", torch.Generator().manual_seed(r), 512, 512,
                                        rotate=True), args.repeats))
            finally:
                geometry.fps_loop_numpy = default
        pts = (anchor - anchor.mean(0)).float()[None]
        far = torch.tensor([r])
        same = same and torch.equal(loops["torch"](pts, 512, far), loops["numpy"](pts, 512, far))
    ms = {name: round(1000 * statistics.median(v), 2) for name, v in per_cloud.items()}
    sample_ms = {name: round(1000 * statistics.median(v), 2) for name, v in per_sample.items()}
    print(json.dumps({
        "command": " ".join(["python", "benchmarks/fps.py", *sys.argv[1:]]),
        "machine": provenance.machine(f"torch {torch.__version__}"),
        "date": provenance.today(),
        "threads": args.threads,
        "ms_per_anchor_cloud_1300_to_512": ms,
        "ms_per_training_sample_cd_512_512": sample_ms,
        "speedup_per_cloud": round(ms["torch"] / ms["numpy"], 2),
        "speedup_per_sample": round(sample_ms["torch"] / sample_ms["numpy"], 2),
        "same_indices": bool(same),
    }, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
