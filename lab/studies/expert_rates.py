"""Pseudo-expert success rates per task and split, one attempt per episode; prints one JSON object.

Each (task, split) runs the first --num episodes of that split's seeds with --max-attempts 1, so the rate is
successes / episodes (multimodal: both holes of each cloth are attempted, 2 episodes per cloth). HangBag rows also
give the episodes that broke the integrity bounds (counted as failures) and the worst stretch, spread and
penetration seen (sim/integrity.py).
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
from pathlib import Path

from tax3d import kept, provenance
from tax3d.sim.generate import Args, generate
from lab.studies import command_line

TASKS = ("hangproccloth-simple", "hangproccloth-unimodal", "hangproccloth-multimodal", "hangbag")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--tasks", default=",".join(TASKS))
    parser.add_argument("--splits", default="unseen,ood")
    parser.add_argument("--num", type=int, default=40)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--keep", type=Path, default=None,
                        help="keep the demonstrations in KEEP/<task>/<split> (rerun `tax3d generate` there to fill gaps)")
    args = parser.parse_args()
    report = {
        "command": command_line(__spec__.name, sys.argv[1:]),
        "machine": provenance.machine(),
        "date": provenance.today(),
        "rates": [],
    }
    for task in args.tasks.split(","):
        for split in args.splits.split(","):
            with tempfile.TemporaryDirectory() as tmp:
                out = Path(tmp) if args.keep is None else args.keep / task / split
                a = Args(task=task, split=split, num=args.num, out=out, workers=args.workers, max_attempts=1)
                stats = generate(a, progress=False)
            if stats["skipped"]:
                print(f"expert_rates: {out} already holds demos; use an empty folder", file=sys.stderr)
                return 2
            row = {k: stats[k] for k in ("episodes", "successes", "exploded", "success_rate", "seconds_per_episode")}
            if stats["integrity"]:
                row.update(broken=stats["broken"], worst=stats["integrity"], failed=stats["failed"])
            report["rates"].append({"task": task, "split": split, **row})
            print(json.dumps(report["rates"][-1]), file=sys.stderr, flush=True)
    print(json.dumps(kept.stamp("expert-rates", 1, report), indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
