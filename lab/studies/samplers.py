"""How much a checkpoint's goals depend on its sampler: the same demos, seed and samples with each of SAMPLERS.

    python -m lab.studies.samplers --checkpoint runs/cd/best --demos data/unimodal/unseen [--samples 5] [--seed 0]

Prints one JSON object: per sampler (the 10-step respaced DDPM, the 10-step DDIM and the 100-step DDPM) the mean
over demos of the min-over-samples RMSE, the mean RMSE of all samples and that of each demo's medoid sample, as
`tax3d predict --steps S --sampler NAME` prints them for each alone.
"""

from __future__ import annotations

import argparse
import json
import sys

import numpy as np

from tax3d import provenance
from tax3d import kept
from tax3d.data.dataset import demo_files
from tax3d.data.format import load_demo
from tax3d.model.tax3d import Tax3D
from tax3d.metrics import medoid_rmse, rmse
from lab.studies import command_line

SAMPLERS = ((10, "ddpm"), (10, "ddim"), (100, "ddpm"))  # (steps, sampler)


def compare(model: Tax3D, demos: list[dict], samples: int, seed: int, max_points: int | None = None) -> dict:
    scenes = [(d["action_pc"], d["anchor_pc"]) for d in demos]
    out = {}
    for steps, sampler in SAMPLERS:
        goals = model.predict_scenes(scenes, num_samples=samples, steps=steps, sampler=sampler, seed=seed,
                                     max_points=max_points)
        errors = np.stack([rmse(g, d["action_pc"] + d["flow"]) for g, d in zip(goals, demos)])  # (D, K)
        out[f"{sampler}_{steps}"] = {"rmse_min_of_samples": float(errors.min(1).mean()),
                                     "rmse_mean": float(errors.mean()), "rmse_medoid": medoid_rmse(goals, errors)}
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--checkpoint", required=True)
    parser.add_argument("--demos", nargs="+", required=True)
    parser.add_argument("--samples", type=int, default=5)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--max-points", type=int, default=None)
    args = parser.parse_args(argv)
    model = Tax3D.from_pretrained(args.checkpoint)
    if not model.spec.diffusion:
        parser.error(f"--checkpoint {args.checkpoint}: a {model.spec.name} checkpoint has no sampler")
    demos = [load_demo(path) for path in demo_files(args.demos)]
    result = {"command": command_line(__spec__.name, sys.argv[1:] if argv is None else argv),
              "date": provenance.today(), "machine": provenance.machine(), "checkpoint": args.checkpoint,
              "demos": len(demos), "samples": args.samples, "seed": args.seed,
              "samplers": compare(model, demos, args.samples, args.seed, args.max_points)}
    print(json.dumps(kept.stamp("samplers", 1, result), indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
