"""Keep the lines of a training run's log.jsonl that a model card and a results page read, the plan, every
validation and the last step, as a small JSON file `{"source": ..., "records": [...]}` (scripts/model_card.py --log).

    python scripts/keep_log.py runs/ttq21/x0-grip16-all506-110min docs/results/training/NAME-log.json
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

from tax3d.atomic import write_json
from tax3d.checkpoint import read_log


def main(argv: list[str]) -> int:
    if len(argv) != 2:
        print("usage: python scripts/keep_log.py RUN_DIR OUT_JSON", file=sys.stderr)
        return 2
    source = Path(argv[0]) / "log.jsonl"
    try:
        records = read_log(source)
    except (OSError, ValueError) as err:
        print(f"error: {source}: not a readable training log ({type(err).__name__}); expected RUN_DIR/log.jsonl "
              f"as `tax3d train` writes it", file=sys.stderr)
        return 2
    if not records:
        print(f"error: {source}: no records; expected at least one logged step", file=sys.stderr)
        return 2
    kept = [r for r in records if "plan" in r or "val_rmse" in r]
    if not kept or kept[-1] is not records[-1]:
        kept.append(records[-1])
    write_json(Path(argv[1]), {"source": f"{source}: the plan, every validation and the last step", "records": kept},
               indent=1)
    print(argv[1])
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
