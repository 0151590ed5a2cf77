"""Keep a training run's validation curve (the validated steps of its log.jsonl) as a small JSON file, so that a
results page can show how the validation RMSE moved with the steps.

    python scripts/val_curve.py runs/NAME docs/results/evals/NAME-curve.json
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

from tax3d.atomic import write_text
from tax3d.checkpoint import read_log


def read_curve(run: Path) -> dict:
    """The run's variant, its validation demos and one entry per validated step; ValueError names what is wrong."""
    log, config = run / "log.jsonl", run / "config.json"
    try:
        cfg = json.loads(config.read_text())
        lines = read_log(log)
    except (OSError, ValueError) as err:
        raise ValueError(f"{run}: no readable config.json and log.jsonl ({type(err).__name__}); expected a "
                         f"`tax3d train` output folder") from None
    points = [{"step": d["step"], "val_rmse": d["val_rmse"], "val_rmse_mean": d.get("val_rmse_mean"),
               **({"val_coverage_rmse": d["val_coverage_rmse"]} if "val_coverage_rmse" in d else {}),
               **({"val_grip_error": d["val_grip_error"]} if "val_grip_error" in d else {}),
               "minutes": round(d["seconds"] / 60, 1)} for d in lines if "val_rmse" in d]
    if not points:
        raise ValueError(f"{log}: no validated step; expected lines with val_rmse")
    return {"run": str(run), "variant": cfg["model"]["variant"], "val": cfg["data"]["val"],
            "val_demos": cfg["train"]["val_demos"], "val_samples": cfg["train"]["val_samples"],
            "steps": cfg["train"]["steps"], "points": points}


def main(argv: list[str]) -> int:
    if len(argv) != 2:
        print("usage: python scripts/val_curve.py RUN_DIR OUT_JSON", file=sys.stderr)
        return 2
    try:
        curve = read_curve(Path(argv[0]))
    except ValueError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    write_text(Path(argv[1]), json.dumps(curve, indent=1) + "\n")
    print(argv[1])
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
