"""`tax3d demo`: the main job on its embedded default (HangProcCloth-simple, fresh unseen anchor poses)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from tax3d.data.format import list_demos, load_demo
from tax3d.plots import plot_demos
from tax3d.sim.generate import Args as GenerateArgs
from tax3d.sim.generate import generate


@dataclass
class Args:
    """Generate a few pseudo-expert demonstrations of HangProcCloth-simple and draw them."""

    out: Path = Path("out/demo")
    """output folder"""
    num: int = 2
    """demonstrations to generate"""
    workers: int = 2
    """worker processes"""


def run(args: Args) -> int:
    demos_dir = args.out / "demos"
    stats = generate(
        GenerateArgs(task="hangproccloth-simple", split="unseen", num=args.num, out=demos_dir,
                     workers=args.workers, render="gif")
    )  # fmt: skip
    print(
        f"expert success {stats['successes']}/{stats['episodes']}, "
        f"{stats['seconds_per_episode']:.1f} s per episode ({stats['skipped']} demos already there)"
    )
    files = list_demos(demos_dir)[: args.num]
    picture = plot_demos([load_demo(f) for f in files], [f.name for f in files], args.out / "demos.png")
    print(f"demonstrations: {demos_dir}")
    print(f"picture: {picture}")
    print(f"animations: {demos_dir / 'renders'}")
    return 0
