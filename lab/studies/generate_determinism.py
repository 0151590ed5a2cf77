"""Are a cloth's demonstrations the same whatever its worker simulated before? Prints one JSON object.

Makes the demonstrations of one cloth alone, and again right after the cloth before it in the same call (one
worker), then the largest difference of their arrays. `--shared-process` runs both cloths in one process, as
generation did before each cloth got a process of its own.

    python -m lab.studies.generate_determinism [--task hangproccloth-multimodal --split unseen --first-index 100]
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

import numpy as np

import tax3d.parallel
import tax3d.sim.generate as generate_module
from tax3d import provenance
from tax3d.sim.tasks import get_task

KEYS = ("action_pc", "anchor_pc", "flow")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--task", default="hangproccloth-multimodal")
    parser.add_argument("--split", default="unseen")
    parser.add_argument("--first-index", type=int, default=100)
    parser.add_argument("--shared-process", action="store_true")
    args = parser.parse_args()
    if args.shared_process:
        generate_module.run_each = lambda *a, **k: tax3d.parallel.run_each(*a, **{**k, "fresh": False})
    per = get_task(args.task).demos_per_cloth
    root, seconds = Path(tempfile.mkdtemp(prefix="tax3d-determinism-")), {}
    for name, first, num in (("after", args.first_index - per, 2 * per), ("alone", args.first_index, per)):
        start = time.perf_counter()
        generate_module.generate(generate_module.Args(task=args.task, split=args.split, first_index=first, num=num,
                                                      out=root / name, workers=1), progress=False)
        seconds[name] = round(time.perf_counter() - start, 1)
    diff = {}
    for i in range(args.first_index, args.first_index + per):
        a, b = (np.load(root / name / f"demo_{i}.npz", allow_pickle=True) for name in ("after", "alone"))
        diff[f"demo_{i}"] = max(float(np.abs(a[k] - b[k]).max()) for k in KEYS)
    print(json.dumps({"task": args.task, "split": args.split, "shared_process": args.shared_process,
                      "max_abs_diff": diff, "seconds": seconds, "machine": provenance.machine()}))


if __name__ == "__main__":
    main()
