"""`tax3d generate`: demonstrations of a task's split in the official file layout (tax3d.sim.generate), with the
expert's success rate and what was written."""

from __future__ import annotations

from tax3d.sim.generate import Args, generate

__all__ = ["Args", "run"]


def run(args: Args) -> int:
    stats = generate(args)
    rate = stats["success_rate"]
    if stats["episodes"] == 0:
        camera = f"; wrote {stats['camera_written']} camera demos to {args.camera_out}" if stats.get("camera_written") else ""
        print(f"nothing to generate: the {stats['skipped']} demos asked for are already in {args.out}{camera}")
        return 0
    print(
        f"expert success {stats['successes']}/{stats['episodes']} episodes ({rate:.0%}), "
        f"{stats['seconds_per_episode']:.1f} s per episode, {stats['exploded']} exploded"
        + (f", {stats['broken']} torn or tunnelled" if stats["broken"] else "")
        + "; "
        f"wrote {stats['written']} demos to {args.out} ({stats['skipped']} already there"
        + (f", {len(stats['failed'])} failed: {' '.join(stats['failed'][:5])}" if stats["failed"] else "")
        + ")"
        + (f"; {stats['camera_written']} camera demos to {args.camera_out}" if args.camera_out is not None else "")
    )
    return 0 if not stats["failed"] else 1

