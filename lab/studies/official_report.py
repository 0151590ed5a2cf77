"""The official-data checkpoint on the official `val` split: RMSE beside the paper's and the mean-goal baseline.

    python -m lab.studies.official_report [--checkpoint checkpoints/tax3d-cd-official-simple] [--samples 5]

Measures on the authors' data (../shared beside the project) and writes docs/results/official_val.json; the page,
docs/results/official-simple.md, is built from it (and from docs/results/model_benchmark.json) by
`python -m lab.results official-simple`.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np
import torch

from tax3d import kept, provenance
from tax3d.atomic import write_text
from lab.studies import command_line

ROOT = Path(__file__).resolve().parents[2]
RESULTS = ROOT / "docs" / "results"
OFFICIAL = ROOT.parent / "shared" / "data" / "tax3d-official" / "hangproccloth-simple"


def measure(checkpoint: Path, samples: int, seed: int) -> dict:
    from tax3d.data.dataset import demo_files
    from tax3d.data.format import load_demo
    from tax3d.metrics import rmse
    from tax3d.policies.fixed import MeanGoalBaseline
    from tax3d.model.tax3d import Tax3D

    model = Tax3D.from_pretrained(checkpoint)
    train = [load_demo(p) for p in demo_files([OFFICIAL / "train"])]
    val = [load_demo(p) for p in demo_files([OFFICIAL / "val"])]
    truth = [d["action_pc"] + d["flow"] for d in val]
    baseline = MeanGoalBaseline.fit(train)
    base = [float(rmse(baseline.predict(d["action_pc"], d["anchor_pc"]), t)) for d, t in zip(val, truth)]
    out = {
        "command": command_line(__spec__.name, sys.argv[1:]),
        "checkpoint": str(checkpoint.relative_to(ROOT) if checkpoint.is_relative_to(ROOT) else checkpoint),
        "machine": provenance.machine(f"torch {torch.__version__}"),
        "date": provenance.today(),
        "demos": len(val), "samples": samples, "seed": seed,
        "mean_goal_baseline_rmse": float(np.mean(base)),
        "samplers": {},
    }
    for name, steps, sampler in (("ddpm_100", 100, "ddpm"), ("ddim_10", 10, "ddim")):
        start = time.perf_counter()
        goals = model.predict_scenes([(d["action_pc"], d["anchor_pc"]) for d in val], num_samples=samples,
                                     steps=steps, sampler=sampler, seed=seed)
        errors = np.stack([rmse(g, t) for g, t in zip(goals, truth)])  # (D, K)
        out["samplers"][name] = {
            "rmse": float(errors.mean()),
            "rmse_per_sample_index": [float(x) for x in errors.mean(0)],
            "rmse_min_of_samples": float(errors.min(1).mean()),
            "rmse_median_demo": float(np.median(errors.mean(1))),
            "rmse_max_demo": float(errors.mean(1).max()),
            "seconds": round(time.perf_counter() - start, 1),
        }
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--checkpoint", type=Path, default=ROOT / "checkpoints" / "tax3d-cd-official-simple")
    parser.add_argument("--samples", type=int, default=5)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    if not (OFFICIAL / "val").is_dir():
        sys.exit(f"{OFFICIAL / 'val'}: official data not found; expected ../shared beside the project")
    val_json = RESULTS / "official_val.json"
    report = kept.stamp("official-val", 1, measure(args.checkpoint.resolve(), args.samples, args.seed))
    write_text(val_json, json.dumps(report, indent=2) + "\n")
    print(val_json)
    print("run `python -m lab.results official-simple` to rebuild docs/results/official-simple.md")


if __name__ == "__main__":
    main()
