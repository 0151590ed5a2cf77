"""`tax3d predict`: goal clouds for demonstration files from a checkpoint, and their RMSE where a demo has a goal.

    tax3d predict --checkpoint checkpoints/tax3d-cd-official-simple --demos DIR --samples 5 --out preds.npz

The npz holds `goals` (D, K, N, 3) world-frame predictions (where the demos' point counts differ, N is the largest
and demo i's rows from points[i] on are NaN), `points` (D,) the action points of each demo, `files` (D,) and
`rmse` (D, K); it loads without allow_pickle. The printed RMSE is the mean over demos of the
min over samples (docs/reference.md, Evaluation), the mean over all samples and that of each demo's medoid sample
(the one nearest the others); `--summary FILE` keeps it as JSON with the command, machine and date (kind
"predict", tax3d.kept).
The repository's `python -m lab.studies.samplers` scores the same demos and seed with each sampler.
"""

from __future__ import annotations


import json
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, Literal, Optional

import numpy as np
import torch

from tax3d import kept, provenance
from tax3d.atomic import atomic_write, write_text
from tax3d.data.dataset import demo_files
from tax3d.data.format import load_demo
from tax3d.metrics import medoid_rmse, rmse
from tax3d.policies.fixed import MeanGoalBaseline
from tax3d.devices import pick_device
from tax3d.model.tax3d import Tax3D
from tax3d import options
from tax3d.options import NonNegative, OutputFile, Positive


@dataclass
class Args:
    """Predict goal clouds for demonstrations with a trained checkpoint."""

    checkpoint: str
    """checkpoint directory (config.json + model.safetensors)"""
    demos: tuple[str, ...]
    """demo folders or demo_N.npz files"""
    samples: Annotated[int, Positive] = 1
    """predictions per demo"""
    steps: Annotated[Optional[int], Positive] = None
    """denoising steps (default: the checkpoint's diffusion.sample_steps)"""
    sampler: Optional[Literal["ddpm", "ddim"]] = None
    """default: the checkpoint's diffusion.sampler"""
    seed: int = 0
    """seed of the diffusion noise (and of the farthest-point samples): the same seed, the same predictions"""
    out: Annotated[Optional[str], OutputFile] = None
    """npz file for the predictions (written atomically)"""
    variant: Optional[str] = None
    """if given, the checkpoint must be of this variant"""
    baseline: tuple[str, ...] = ()
    """demo folders to fit the mean-goal baseline on (e.g. the training split); its RMSE is printed too"""
    summary: Annotated[Optional[str], OutputFile] = None
    """JSON file for the printed summary, with the command, machine and date beside it (written atomically)"""
    threads: Annotated[int, NonNegative] = 0
    """torch CPU threads (0: torch's default)"""
    max_points: Annotated[Optional[int], NonNegative] = None
    """the network runs on at most this many action points, the others taking the distance-weighted displacement of
    their nearest sampled ones (default: the checkpoint's data.predict_points, else the number it was trained on;
    0: every point; SD/SP: always the number it was trained on)"""
    batch_scenes: Annotated[int, Positive] = 8
    """demos denoised together in one batch"""
    device: str = "cpu"
    """cpu, cuda, cuda:K or auto (CUDA when there is one)"""


def run(args: Args) -> int:
    options.check(args)  # --out and --summary writable, numbers in range, also when called from Python
    if args.threads > 0:
        torch.set_num_threads(args.threads)
    device = pick_device(args.device)
    model = Tax3D.from_pretrained(args.checkpoint, variant=args.variant, map_location=device)
    if model.spec.diffusion:
        model.sampling(args.steps, args.sampler, "--")
    files = demo_files(args.demos)
    demos = [load_demo(path) for path in files]

    started = time.time()
    scenes = [(d["action_pc"], d["anchor_pc"]) for d in demos]
    goals = model.predict_scenes(scenes, num_samples=args.samples, steps=args.steps, sampler=args.sampler,
                                 max_points=args.max_points,
                                 seed=args.seed, batch_scenes=args.batch_scenes, progress=True)
    seconds = time.time() - started
    errors = np.stack([rmse(g, d["action_pc"] + d["flow"]) for g, d in zip(goals, demos)])  # (D, K)

    summary = {"demos": len(demos), "samples": args.samples, "steps": args.steps or model.config.diffusion.sample_steps,
               "rmse_min_of_samples": float(errors.min(1).mean()), "rmse_mean": float(errors.mean()),
               "rmse_medoid": medoid_rmse(goals, errors), "seconds": round(seconds, 2)}
    if args.baseline:
        baseline = MeanGoalBaseline.fit([load_demo(p) for p in demo_files(args.baseline)])
        summary["rmse_mean_goal_baseline"] = float(np.mean(
            [rmse(baseline.predict(d["action_pc"], d["anchor_pc"]), d["action_pc"] + d["flow"]) for d in demos]))
    if args.out:
        write_npz(Path(args.out), goals, files, errors)
        print(f"predictions: {args.out}", file=sys.stderr)
    if args.summary:
        record = kept.stamp("predict", 1, {**provenance.made("tax3d.cli.predict"), "checkpoint": str(args.checkpoint),
                                           **summary})
        Path(args.summary).parent.mkdir(parents=True, exist_ok=True)
        write_text(args.summary, json.dumps(record, indent=1) + "\n")
        print(f"summary: {args.summary}", file=sys.stderr)
    print(json.dumps(summary))
    return 0


def write_npz(path: Path, goals: list[np.ndarray], files: list[Path], errors: np.ndarray) -> None:
    """goals (K, N_i, 3) per demo, stacked into one plain array, padded with NaN where the N_i differ."""
    points = np.array([g.shape[1] for g in goals])
    stacked = np.full((len(goals), goals[0].shape[0], points.max(), 3), np.nan)
    for i, g in enumerate(goals):
        stacked[i, :, :len(g[0])] = g
    path.parent.mkdir(parents=True, exist_ok=True)

    def write(tmp: Path) -> None:
        with open(tmp, "wb") as f:
            np.savez(f, goals=stacked, points=points, files=np.array([str(p) for p in files]), rmse=errors)

    atomic_write(path, write)

