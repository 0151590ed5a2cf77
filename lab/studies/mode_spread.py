"""How far apart the two goals of a multimodal cloth are, and what predicting their average would score; prints JSON.

    python -m lab.studies.mode_spread --data data/multimodal [--out FILE]

Per split, over the cloths with both demonstrations (one per hole, same anchor pose): the RMSE between the two goals
(the separation of the modes), and the RMSE of their point-wise midpoint to either goal, which is then that
prediction's coverage and precision RMSE alike: what a regression that averages the two modes would score.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from tax3d.atomic import write_json
from tax3d import kept, provenance
from tax3d.data.format import cloth_groups
from tax3d.metrics import rmse
from lab.studies import command_line


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, required=True, help="folder with train, unseen, ood demo folders")
    parser.add_argument("--out", type=Path, default=None, help="write the JSON here too")
    args = parser.parse_args()
    splits = [s for s in ("train", "unseen", "ood") if (args.data / s).is_dir()]
    if not splits:
        print(f"error: --data {args.data}: expected train, unseen or ood folders of demo_N.npz files inside it",
              file=sys.stderr)
        return 2
    out = {"command": command_line(__spec__.name, sys.argv[1:]), "date": provenance.today(), "splits": {}}
    for split in splits:
        pairs = [[d["action_pc"] + d["flow"] for d in g] for g in cloth_groups(args.data / split) if len(g) == 2]
        out["splits"][split] = {
            "cloths_with_both_goals": len(pairs),
            "goal_separation_rmse": float(np.mean([rmse(a, b) for a, b in pairs])) if pairs else None,
            "midpoint_rmse": float(np.mean([rmse((a + b) / 2, a) for a, b in pairs])) if pairs else None}
    print(write_json(args.out, kept.stamp("mode-spread", 1, out)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
