"""How much each checkpoint's goal RMSE depends on the sampler: the min over samples of the RMSE (docs/reference.md,
Evaluation) with the respaced 10-step DDPM, the 10-step DDIM and the full 100-step DDPM, on the same demos, seed
and noise. Prints JSON and, with --out, keeps it with the command, machine and date.

    python scripts/sampler_check.py --demos data/multimodal/unseen --first 10 \
        --checkpoints runs/multimodal-sd/best runs/multimodal-sp/best --out docs/results/evals/multimodal-samplers.json
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path

import numpy as np
import torch

from tax3d import provenance
from tax3d.atomic import write_text
from tax3d.data.dataset import demo_files
from tax3d.data.format import load_demo
from tax3d.errors import UsageError
from tax3d.metrics import min_of_samples_rmse
from tax3d.model.tax3d import Tax3D

SETTINGS = ((10, "ddpm"), (10, "ddim"), (100, "ddpm"))


def check(checkpoint: str, demos: list[dict], samples: int, seed: int) -> dict:
    model = Tax3D.from_pretrained(checkpoint)
    scenes = [(d["action_pc"], d["anchor_pc"]) for d in demos]
    row = {"checkpoint": checkpoint, "variant": model.config.model.variant}
    for steps, sampler in SETTINGS:
        goals = model.predict_scenes(scenes, num_samples=samples, steps=steps, sampler=sampler, seed=seed)
        errors = [min_of_samples_rmse(g, d["action_pc"] + d["flow"]) for g, d in zip(goals, demos)]
        row[f"{sampler}_{steps}"] = float(np.mean(errors))
    return row


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--checkpoints", nargs="+", required=True)
    parser.add_argument("--demos", required=True, help="a demo folder")
    parser.add_argument("--first", type=int, default=10, help="the first N demos of the folder")
    parser.add_argument("--samples", type=int, default=2)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", help="JSON file to keep the result in")
    args = parser.parse_args(argv)
    torch.set_num_threads(max(1, os.cpu_count() or 1))
    try:
        files = demo_files([args.demos])[: args.first]
        demos = [load_demo(path) for path in files]
        rows = [check(c, demos, args.samples, args.seed) for c in args.checkpoints]
    except (UsageError, FileNotFoundError, ValueError) as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    result = {"command": "python scripts/sampler_check.py " + " ".join(argv if argv is not None else sys.argv[1:]),
              "date": provenance.today(),
              "machine": provenance.machine(),
              "demos": len(demos), "samples": args.samples, "seed": args.seed, "rows": rows}
    text = json.dumps(result, indent=1) + "\n"
    if args.out:
        Path(args.out).parent.mkdir(parents=True, exist_ok=True)
        write_text(args.out, text)
    print(text, end="")
    return 0


if __name__ == "__main__":
    sys.exit(main())
