"""Kept as a script, being neither a command nor a measurement: copies demonstrations without their trajectories.

    python scripts/strip_trajectories.py SRC_DIR DST_DIR

A multimodal training demo is about 2 MB with trajectories and 0.1 MB without: the copy is what to ship to a
machine that trains TAX3D alone. Each file is written to a temporary name and renamed.
"""

from __future__ import annotations

import sys
from pathlib import Path

from tax3d.data.format import strip_trajectories


def main() -> int:
    if len(sys.argv) != 3 or not Path(sys.argv[1]).is_dir():
        print("usage: python scripts/strip_trajectories.py SRC_DIR DST_DIR (SRC_DIR: a folder of demo_*.npz)",
              file=sys.stderr)
        return 2
    src, dst = Path(sys.argv[1]), Path(sys.argv[2])
    dst.mkdir(parents=True, exist_ok=True)
    files = sorted(src.glob("demo_*.npz"))
    for path in files:
        strip_trajectories(path, dst / path.name)
    print(f"{len(files)} demos from {src} to {dst}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
