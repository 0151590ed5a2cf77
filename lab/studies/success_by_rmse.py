"""Success of the policy against the RMSE of the goal it executed, from one `tax3d eval` run: how close a goal must be
for the cloth to hang. Kept as a small JSON that a results page cites.

    python -m lab.studies.success_by_rmse runs/eval-x docs/results/evals/NAME-success-by-rmse.json [--splits unseen,ood]

Episodes are pooled over the splits and put in RMSE bins (--edges); each bin gives its episodes and success rate.
The RMSE is the executed sample's (`executed_rmse`, recorded by `tax3d eval`), so runs made before it was recorded
are refused. `--by executed_grip_error` bins by the executed goal's mean distance from the demonstration's at the two
grasped vertices, the points the policy moves the grippers to.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from tax3d import kept, provenance
from tax3d.atomic import write_text
from lab.studies import command_line


def bins(episodes: list[dict], edges: list[float], by: str = "executed_rmse") -> list[dict]:
    bounds = list(zip(edges, edges[1:] + [None]))
    out = []
    for low, high in bounds:
        inside = [e for e in episodes if e[by] >= low and (high is None or e[by] < high)]
        out.append({"low": low, "high": high, "episodes": len(inside),
                    "success_rate": sum(e["success"] for e in inside) / len(inside) if inside else None})
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("eval_dir", type=Path)
    parser.add_argument("out", type=Path)
    parser.add_argument("--splits", default="unseen,ood")
    parser.add_argument("--edges", default="0,0.25,0.5,0.75,1.0", help="lower edges of the RMSE bins, ascending")
    parser.add_argument("--by", choices=("executed_rmse", "executed_grip_error"), default="executed_rmse",
                        help="bin by the executed goal's RMSE or by its mean distance at the grasped vertices")
    args = parser.parse_args(argv)
    source = args.eval_dir / "results.json"
    try:
        results = json.loads(source.read_text())
        episodes, summary = results["episodes"], results["summary"]
    except (OSError, ValueError, KeyError) as err:
        print(f"error: {source}: not a readable tax3d eval results file ({type(err).__name__}); expected "
              f"EVAL_DIR/results.json with episodes and a summary", file=sys.stderr)
        return 2
    try:
        edges = [float(v) for v in args.edges.split(",")]
    except ValueError:
        edges = []
    if not edges or edges != sorted(set(edges)):
        print(f"error: --edges {args.edges}: expected ascending numbers, comma-separated", file=sys.stderr)
        return 2
    splits = [s for s in args.splits.split(",") if s]
    chosen = [e for e in episodes if e["split"] in splits and e.get(args.by) is not None]
    if not chosen:
        print(f"error: {source}: no episode of {', '.join(splits)} has an {args.by}; expected a run of "
              f"`tax3d eval` on demo folders", file=sys.stderr)
        return 2
    record = {"command": command_line(__spec__.name, sys.argv[1:] if argv is None else argv),
            "source": summary.get("command"), "checkpoint": summary.get("checkpoint"), "pooled_splits": splits,
            "samples": summary.get("args", {}).get("samples"), "select": summary.get("args", {}).get("select"),
            "episodes": len(chosen), "success_rate": sum(e["success"] for e in chosen) / len(chosen),
            "by": args.by, "bins": bins(chosen, edges, args.by), "machine": summary.get("machine"),
            "date": provenance.today()}
    write_text(args.out, json.dumps(kept.stamp("success-by-rmse", 1, record), indent=1) + "\n")
    print(args.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
