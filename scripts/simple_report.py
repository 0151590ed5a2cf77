"""Write docs/results/hangproccloth-simple.md: `scripts/task_report.py --task hangproccloth-simple`.

Usage: python scripts/simple_report.py --eval CD=runs/simple-cd/eval CP=runs/simple-cp/eval --train-command "..."
"""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from task_report import main  # noqa: E402

if __name__ == "__main__":
    main(["--task", "hangproccloth-simple", *sys.argv[1:]])
