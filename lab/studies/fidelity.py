"""Fidelity of our HangProcCloth scene to the official demonstrations; prints one JSON object.

For every official demo: our initial cloth vertices against its action_pc (max abs difference, same vertex order)
and our anchor cloud against its anchor_pc (mean symmetric nearest-neighbour distance). For the first
--episodes demos of each split: the pseudo-expert replayed on the same cloth and anchor pose, and the RMSE of
our goal cloud to the official goal (action_pc + flow).
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
from pathlib import Path

import numpy as np

from tax3d import kept, provenance
from tax3d.data.format import list_demos, load_demo
from tax3d.sim.env import HangClothEnv
from tax3d.sim.generate import Args, generate
from lab.studies import command_line

DEFAULT = Path(__file__).resolve().parents[2].parent / "shared" / "data" / "tax3d-official" / "hangproccloth-simple"


def mean_symmetric_nn(a: np.ndarray, b: np.ndarray) -> float:
    d = np.sqrt(((a[:, None, :] - b[None, :, :]) ** 2).sum(-1))
    return float((d.min(1).mean() + d.min(0).mean()) / 2)


def reset_checks(folder: Path) -> dict:
    init_err, anchor_nn = [], []
    envs = {}
    for path in list_demos(folder):
        demo = load_demo(path)
        trans = demo["trans"]
        floor = bool(demo["anchor_pc"][:, 2].min() >= trans[2] - 0.05)
        if floor not in envs:
            envs[floor] = HangClothEnv(floor=floor)
        env = envs[floor]
        state = env.reset(demo["deform_params"], demo["rot"][2], trans)
        init_err.append(float(np.abs(state.cloth - demo["action_pc"]).max()))
        anchor_nn.append(mean_symmetric_nn(env.anchor_points(), demo["anchor_pc"]))
    for env in envs.values():
        env.close()
    return {
        "demos": len(init_err),
        "init_max_abs_diff": max(init_err),
        "anchor_nn_mean": float(np.mean(anchor_nn)),
        "anchor_nn_max": max(anchor_nn),
    }


def expert_checks(folder: Path, episodes: int, workers: int) -> dict:
    with tempfile.TemporaryDirectory() as out:
        stats = generate(Args(replay=folder, num=episodes, out=Path(out), workers=workers), progress=False)
        rmse = []
        for path in list_demos(folder)[:episodes]:
            ours = Path(out) / path.name
            if ours.exists():
                mine, theirs = load_demo(ours), load_demo(path)
                err = (mine["action_pc"] + mine["flow"]) - (theirs["action_pc"] + theirs["flow"])
                rmse.append(float(np.sqrt((err**2).sum(1).mean())))
    return {
        "episodes": stats["episodes"],
        "expert_success": stats["success_rate"],
        "seconds_per_episode": stats["seconds_per_episode"],
        "goal_rmse_mean": float(np.mean(rmse)) if rmse else None,
        "goal_rmse_median": float(np.median(rmse)) if rmse else None,
        "goal_rmse_max": float(np.max(rmse)) if rmse else None,
        "goal_rmse_under_0.5": int(np.sum(np.array(rmse) < 0.5)),
    }


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--official", type=Path, default=DEFAULT)
    parser.add_argument("--episodes", type=int, default=40, help="expert replays per split (0: none)")
    parser.add_argument("--workers", type=int, default=2)
    args = parser.parse_args()
    if not args.official.is_dir():
        print(f"fidelity: error: {args.official}: official demonstrations not found", file=sys.stderr)
        return 2
    report = {
        "command": command_line(__spec__.name, sys.argv[1:]),
        "machine": provenance.machine(),
        "date": provenance.today(),
    }
    for split in ("train", "val"):
        folder = args.official / split
        report[split] = reset_checks(folder)
        if args.episodes > 0:
            report[split].update(expert_checks(folder, args.episodes, args.workers))
    print(json.dumps(kept.stamp("fidelity", 1, report), indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
