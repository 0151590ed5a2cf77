"""A checkpoint's training-time validation RMSE with the network on each of several numbers of action points.

    python -m lab.studies.val_points --checkpoint runs/ttq33/b8-p128-30min/best --val data/unimodal/val \
        --points 128 256 0 [--val-demos 20] [--samples 2] [--seed 42]

The same measure as `tax3d train --train.val-points sampled` logs (`tax3d.training.validation.validate`: the mean over the
first `--val-demos` demos of the min-over-samples RMSE on whole clouds, the checkpoint's own sampler and steps),
with `predict`'s max_points set to each of `--points` in turn (0: every point). Defaults: the checkpoint's
train.val_demos, train.val_samples and train.seed, so that its own number of points repeats its log. Prints one
JSON object.
"""

from __future__ import annotations

import argparse
import json
import sys

from tax3d import kept, provenance
from tax3d.data.dataset import demo_files
from tax3d.data.format import load_demo
from tax3d.model.tax3d import Tax3D
from tax3d.training.validation import validate
from lab.studies import command_line


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--checkpoint", required=True)
    parser.add_argument("--val", nargs="+", required=True)
    parser.add_argument("--points", type=int, nargs="+", required=True)
    parser.add_argument("--val-demos", type=int, default=None)
    parser.add_argument("--samples", type=int, default=None)
    parser.add_argument("--seed", type=int, default=None)
    args = parser.parse_args(argv)
    if any(p < 0 for p in args.points):
        parser.error(f"--points {' '.join(map(str, args.points))}: expected 0 (every point) or positive numbers")
    model = Tax3D.from_pretrained(args.checkpoint)
    train = model.config.train
    count = train.val_demos if args.val_demos is None else args.val_demos
    files = demo_files(args.val)
    demos = [load_demo(path) for path in (files[:count] if count > 0 else files)]
    samples = train.val_samples if args.samples is None else args.samples
    seed = train.seed if args.seed is None else args.seed
    rows = {}
    for points in args.points:
        model.config.data.predict_points = points
        rows[str(points)] = validate(model, demos, samples, seed=seed, points="sampled")
    result = {"command": command_line(__spec__.name, sys.argv[1:] if argv is None else argv),
              "date": provenance.today(), "machine": provenance.machine(), "checkpoint": args.checkpoint,
              "trained_points": model.config.data.num_action_points, "demos": len(demos), "samples": samples,
              "seed": seed, "points": rows}
    print(json.dumps(kept.stamp("val-points", 1, result), indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
