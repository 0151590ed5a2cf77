"""Keep the summary of a `tax3d eval` run (its results.json without the per-episode clouds) as a small JSON file, so
that a results page can be rebuilt from committed files.

    python scripts/keep_summary.py runs/eval-x docs/results/evals/NAME.json [--splits unseen,ood]

--splits keeps only those splits (recorded as `kept_splits`), such as the ones scored on demonstrations when the run
also scored a split whose folder was missing.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

from tax3d.atomic import write_text


def main(argv: list[str]) -> int:
    keep = None
    if len(argv) == 4 and argv[2] == "--splits":
        keep, argv = argv[3].split(","), argv[:2]
    if len(argv) != 2:
        print("usage: python scripts/keep_summary.py EVAL_DIR OUT_JSON [--splits A,B]", file=sys.stderr)
        return 2
    source = Path(argv[0]) / "results.json"
    try:
        summary = json.loads(source.read_text())["summary"]
    except (OSError, ValueError, KeyError) as err:
        print(f"error: {source}: not a readable tax3d eval results file ({type(err).__name__}); expected "
              f"EVAL_DIR/results.json with a summary", file=sys.stderr)
        return 2
    if keep is not None:
        missing = [k for k in keep if k not in summary["splits"]]
        if missing:
            print(f"error: --splits: {','.join(missing)} not in {source} (it has {','.join(summary['splits'])})",
                  file=sys.stderr)
            return 2
        summary["splits"] = {k: summary["splits"][k] for k in keep}
        summary["kept_splits"] = ",".join(keep)
    write_text(Path(argv[1]), json.dumps({"summary": summary}, indent=1) + "\n")
    print(argv[1])
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
