"""How much of a task's goal variation a fixed goal explains: offline RMSE of mean goals, and the hook's share of
the anchor cloud after farthest point sampling; prints one JSON object.

    python -m lab.studies.goal_spread --data data/hangbag [--points 256 512]

- mean goal: the mean over DATA/train of the goal in the anchor frame (translation to the anchor's mean, the CD/CP
  frame), placed at each demo's anchor (`tax3d.policies.fixed.MeanGoalBaseline`);
- rotated mean goal: the same, in a frame that also turns with the anchor's known z-rotation (an oracle for the
  rotation, which no model is given), so the rest is the deformable's own variation;
- anchor points off the pole: points farther than 0.35 from the pole's axis and above z = trans_z + 8 (the hook
  region of the HangBag anchor), in the full cloud and after FPS to each of --points.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np
import torch

from tax3d import kept, provenance
from tax3d.data.format import list_demos, load_demo
from tax3d.geometry import farthest_point_sample
from tax3d.metrics import rmse
    from tax3d.policies.fixed import MeanGoalBaseline
from lab.studies import command_line


def rot_z(angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def hook_mask(demo: dict) -> np.ndarray:
    anchor, trans = demo["anchor_pc"], demo["trans"]
    axis = np.median(anchor[anchor[:, 2] < trans[2] + 8][:, :2], axis=0)
    return (np.linalg.norm(anchor[:, :2] - axis, axis=1) > 0.35) & (anchor[:, 2] > trans[2] + 8)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, required=True, help="folder with train, unseen, ood demo folders")
    parser.add_argument("--points", type=int, nargs="+", default=[256, 512])
    args = parser.parse_args()
    if not (args.data / "train").is_dir():
        print(f"error: --data {args.data}: expected a train folder of demo_N.npz files inside it", file=sys.stderr)
        return 2
    splits = {s: [load_demo(p) for p in list_demos(args.data / s)] for s in ("train", "unseen", "ood")
              if (args.data / s).is_dir()}
    train = splits["train"]
    mean = MeanGoalBaseline.fit(train)
    turned = np.mean([(d["action_pc"] + d["flow"] - d["anchor_pc"].mean(0)) @ rot_z(d["rot"][2]) for d in train], 0)
    out = {"command": command_line(__spec__.name, sys.argv[1:]), "date": provenance.today(), "splits": {}}
    for name, demos in splits.items():
        goals = [d["action_pc"] + d["flow"] for d in demos]
        plain = [float(rmse(mean.predict(d["action_pc"], d["anchor_pc"]), g)) for d, g in zip(demos, goals)]
        rotated = [float(rmse(turned @ rot_z(d["rot"][2]).T + d["anchor_pc"].mean(0), g)) for d, g in zip(demos, goals)]
        out["splits"][name] = {"demos": len(demos), "mean_goal_rmse": float(np.mean(plain)),
                               "rotated_mean_goal_rmse": float(np.mean(rotated))}
    demo = train[0]
    mask = hook_mask(demo)
    out["anchor_points_off_the_pole"] = {"full": f"{int(mask.sum())} of {len(mask)}"}
    for k in args.points:
        idx = farthest_point_sample(torch.as_tensor(demo["anchor_pc"]), k, start=0).numpy()
        out["anchor_points_off_the_pole"][f"fps_{k}"] = f"{int(mask[idx].sum())} of {k}"
    print(json.dumps(kept.stamp("goal-spread", 1, out), indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
