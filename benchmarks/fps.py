"""Farthest point sampling on the CPU: the numpy loop against the torch loop, per cloud and per training sample.

    python benchmarks/fps.py [--rounds 7] [--threads 1] [--demos DIR ...]

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

import numpy as np
import torch

from tax3d import geometry, provenance
from tax3d import kept
from tax3d.data.dataset import demo_files, make_sample
from tax3d.data.format import load_demo

try:
    import fpsample
except ImportError:
    fpsample = None


def fps_loop_fpsample(pts: torch.Tensor, k: int, far: torch.Tensor) -> torch.Tensor:
    """The `fpsample` package's vanilla FPS, one row at a time, from the same first indices."""
    return torch.from_numpy(np.stack([fpsample.fps_sampling(pts[b].numpy(), k, start_idx=int(far[b]))
                                      for b in range(len(pts))]).astype(np.int64))


def agreement(folders: list[str], loops: dict, starts: int = 4) -> dict:
    """Per loop of `loops`, how many real clouds (action and anchor of each demo, `starts` first indices each, 256 and
    512 points) get the torch loop's indices; the torch loop runs once per cloud."""
    same, total = dict.fromkeys(loops, 0), 0
    for path in demo_files(folders):
        demo = load_demo(path)
        for key in ("action_pc", "anchor_pc"):
            points = torch.as_tensor(demo[key], dtype=torch.float64)
            pts = (points - points.mean(0)).float()[None]
            for k in (256, 512):
                if k >= len(points):
                    continue
                for s in range(starts):
                    far = torch.tensor([s * len(points) // starts])
                    reference = geometry.fps_loop_torch(pts, k, far)
                    for name, loop in loops.items():
                        same[name] += int(torch.equal(loop(pts, k, far), reference))
                    total += 1
    return {name: {"demos": folders, "clouds": total, "same_indices": n} for name, n in same.items()}


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
    parser.add_argument("--demos", nargs="*", default=[], help="demo folders whose clouds check the indices")
    args = parser.parse_args()
    torch.set_num_threads(args.threads)
    action, anchor, goal = clouds()
    loops = {"torch": geometry.fps_loop_torch, "numpy": geometry.fps_loop_numpy}
    if fpsample is not None:
        loops["fpsample"] = fps_loop_fpsample
    default = geometry.fps_loop_numpy
    same = {name: True for name in loops if name != "torch"}
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
        for name in same:
            same[name] = same[name] and torch.equal(loops["torch"](pts, 512, far), loops[name](pts, 512, far))
    ms = {name: round(1000 * statistics.median(v), 2) for name, v in per_cloud.items()}
    sample_ms = {name: round(1000 * statistics.median(v), 2) for name, v in per_sample.items()}
    result = {
        "command": " ".join(["python", "benchmarks/fps.py", *sys.argv[1:]]),
        "machine": provenance.machine(f"torch {torch.__version__}"),
        "date": provenance.today(),
        "threads": args.threads,
        "ms_per_anchor_cloud_1300_to_512": ms,
        "ms_per_training_sample_cd_512_512": sample_ms,
        "speedup_per_cloud": round(ms["torch"] / ms["numpy"], 2),
        "speedup_per_sample": round(sample_ms["torch"] / sample_ms["numpy"], 2),
        "same_indices": bool(same["numpy"]),
    }
    if fpsample is None:
        result["fpsample"] = "not installed: pip install fpsample==1.0.2 to time it"
    else:
        result["fpsample"] = {
            "version": fpsample.__version__,
            "speedup_per_cloud_over_numpy": round(ms["numpy"] / ms["fpsample"], 2),
            "speedup_per_sample_over_numpy": round(sample_ms["numpy"] / sample_ms["fpsample"], 2),
            "same_indices_synthetic": bool(same["fpsample"]),
        }
    if args.demos:
        real = agreement(args.demos, {name: loop for name, loop in loops.items() if name != "torch"})
        result["numpy_real_clouds"] = real["numpy"]
        if "fpsample" in real:
            result["fpsample"]["real_clouds"] = real["fpsample"]
    print(json.dumps(kept.stamp("fps-benchmark", 1, result), indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
