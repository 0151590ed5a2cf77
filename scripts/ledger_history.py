"""Enter into an empty ledger (tax3d.eval.ledger) the scorings of test episodes made before it existed, from git history.

    python scripts/ledger_history.py [--ledger docs/results/table/ledger.jsonl]

Each version of a kept row (docs/results/table/TASK/NUM/ROW.json) that git holds, in commit order, is one scoring,
entered with "source": "git SHA" (the commit that kept it); a row withdrawn and kept again is scored twice. Two
scorings no kept row holds are entered beside the commit that tells of them, with what is known and a note: the
earlier scorings a row counts (`test.scorings`) beyond its versions in git, and STOPPED.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "src"))

from tax3d.eval import ledger  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
TABLE = "docs/results/table"
# The first TAX3D-CD run at 64 multimodal demos was stopped while its test episodes were scored, and no score was
# written (docs/results/hangproccloth-multimodal.md, "The 64-demo TAX3D-CD row was trained twice"; kept with 78dd999)
STOPPED = {("78dd999", f"{TABLE}/hangproccloth-multimodal/64/cd.json"): {
    "date": "2026-12-05", "weights_sha256": None, "data_sha256": None, "episodes": None, "successes": None,
    "note": "the first training run, slowed by subnormal floats, was stopped while its test episodes were scored; "
            "no score was written and the run was discarded"}}


def git(*args: str) -> str:
    return subprocess.run(["git", *args], cwd=ROOT, check=True, capture_output=True, text=True).stdout


def versions():
    """(short sha, path, row) of every version of a kept row added or changed in a commit, oldest first."""
    for sha in git("log", "--reverse", "--format=%h", "--", TABLE).split():
        changed = git("show", "--format=", "--name-status", sha, "--", TABLE).splitlines()
        for status, path in (entry.split("\t", 1) for entry in changed):
            if status in ("A", "M") and path.endswith(".json") and path.count("/") == 5:
                yield sha, path, json.loads(git("show", f"{sha}:{path}"))


def history() -> list[dict]:
    lines, seen = [], {}
    for sha, path, row in versions():
        for key, stopped in STOPPED.items():
            if key == (sha, path):
                lines.append({"task": row["task"], "num_train": row["num_train"], "row": row["variant"],
                              "first_index": row["test"]["first_index"], "command": row["command"], **stopped,
                              "source": f"git {sha}"})
        kept = ledger.scoring(row["task"], row["num_train"], row["variant"], row, row.get("data_sha256"),
                              row["test"]["first_index"], row["command"])
        if seen.get(path) == (kept["weights_sha256"], kept["successes"]):
            continue  # the same scoring, its file changed otherwise
        counted = row["test"]["scorings"] if seen.get(path) is None else 1
        for _ in range(counted - 1):  # scorings the row counts that no version in git holds
            lines.append({**kept, "weights_sha256": None, "data_sha256": None, "successes": None,
                          "command": row["command"].replace(" --retrain", ""), "source": f"git {sha}",
                          "note": f"one of the {row['test']['scorings']} scorings the row counts (test.scorings) that "
                                  "no kept version holds: its result was overwritten before the row was kept"
                                  + ("; the weights it scored were trained again since (--retrain)"
                                     if row.get("trainings", 1) > 1 else "")})
        lines.append({**kept, "source": f"git {sha}"})
        seen[path] = (kept["weights_sha256"], kept["successes"])
    return lines


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--ledger", type=Path, default=ROOT / TABLE / "ledger.jsonl")
    args = parser.parse_args()
    if ledger.read(args.ledger):
        print(f"--ledger {args.ledger}: holds lines already; expected an empty ledger (history goes in first)",
              file=sys.stderr)
        return 2
    for line in history():
        ledger.append(args.ledger, line)
    print(f"{args.ledger}: {len(ledger.read(args.ledger))} scorings from git history")
    return 0


if __name__ == "__main__":
    sys.exit(main())
