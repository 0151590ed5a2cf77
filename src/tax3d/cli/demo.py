"""`tax3d demo`: the main job. The shipped TAX3D-CD checkpoint hangs the cloth for fresh anchor poses."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Annotated

from tax3d.errors import UsageError
from tax3d.cli.eval import Args as EvalArgs
from tax3d.cli.eval import run as run_eval
from tax3d.options import OutputFolder, Positive

SHIPPED = Path(__file__).resolve().parents[3] / "checkpoints" / "tax3d-cd-simple"


@dataclass
class Args:
    """HangProcCloth-simple with the shipped TAX3D-CD checkpoint: fresh unseen and out-of-distribution anchor poses,
    a goal predicted once on the full cloth, open-loop execution, release, success check; a table and a report."""

    checkpoint: Path = SHIPPED
    """checkpoint directory (default: the one shipped in checkpoints/)"""
    episodes: Annotated[int, Positive] = 6
    """fresh episodes per split (unseen, ood)"""
    samples: Annotated[int, Positive] = 3
    """goal samples per episode shown in the report (the policy executes the first)"""
    workers: Annotated[int, Positive] = 2
    """worker processes, each with its own simulator and a copy of the model"""
    out: Annotated[Path, OutputFolder] = Path("out/demo")
    """output folder: results.json, results.md, report.html, images/"""


def run(args: Args) -> int:
    if not (args.checkpoint / "model.safetensors").is_file():
        shipped = (" (the shipped checkpoints are in the repository's checkpoints/ folder, not in an installed "
                   "package: run `make demo` or `pip install -e .` in a clone, or pass --checkpoint "
                   "CLONE/checkpoints/tax3d-cd-simple)") if args.checkpoint == SHIPPED else ""
        raise UsageError(f"--checkpoint {args.checkpoint}: no model.safetensors there; expected a checkpoint "
                         f"folder{shipped}")
    # Indices from 1000 on: poses that none of the generated unseen / ood demonstration sets uses.
    return run_eval(EvalArgs(checkpoint=args.checkpoint, task="hangproccloth-simple", splits="unseen,ood",
                             episodes=args.episodes, samples=args.samples, workers=args.workers, first_index=1000,
                             out=args.out))
