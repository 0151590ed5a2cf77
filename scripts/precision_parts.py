"""Where a checkpoint's samples miss a cloth's goals, and at which denoising step the miss arises; prints JSON.

    python scripts/precision_parts.py CHECKPOINT --data data/multimodal/unseen [--cloths 20] [--samples 5]
        [--steps 30,45,55,65,75,85,99] [--out FILE]

Over the first --cloths cloths of the folder (a cloth's demos share its parameters and anchor pose: two on
multimodal, one for each hole; one on unimodal):
- samples: the goals `predict` draws by default, each against the nearest of the cloth's goals. Its RMSE (the
  precision RMSE of appendix C) splits into the offset (the distance between the sample's and the goal's centroids,
  a rigid translation) and the shape error (the RMSE left once that offset is removed): precision^2 = offset^2 +
  shape^2. `toward_other` (two goals only): the offset's share, along the line between the two goals' centroids,
  of the way to the other goal (0: none, 0.5: the midpoint).
- from_noised_goal: each demo's own goal noised to step t (the forward process), then the checkpoint's x_0 estimate
  at t (x0_rmse, toward_other), and the precision after denoising from there with the DDPM steps t-1 ... 0.
  `bayes_toward_other`: the share an ideal denoiser would lean toward the other goal when the only evidence of the
  hole is the mean of x_t over the network's points (the two goals' centroids as the hypotheses, equal priors).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from tax3d import provenance
from tax3d.atomic import write_json
from tax3d.metrics import rmse

SEED = 0


def lean(sample: np.ndarray, goal: np.ndarray, other: np.ndarray) -> float:
    """How far the sample's centroid has moved from `goal`'s toward `other`'s, as a share of the way."""
    line = other.mean(0) - goal.mean(0)
    return float((sample - goal).mean(0) @ line / (line @ line))


def sample_parts(sample: np.ndarray, goals: list[np.ndarray]) -> dict:
    """One sample (N, 3) against a cloth's goals: precision, offset, shape error and, with two goals, the lean
    toward the other (None with one)."""
    near = int(np.argmin([rmse(sample, g) for g in goals]))
    goal = goals[near]
    offset = (sample - goal).mean(0)
    return {"precision_rmse": float(rmse(sample, goal)), "offset": float(np.linalg.norm(offset)),
            "shape_rmse": float(rmse(sample - offset, goal)),
            "toward_other": lean(sample, goal, goals[1 - near]) if len(goals) == 2 else None}


def bayes_lean(separation: float, abar: float, points: int, rng: np.random.Generator, draws: int = 20000) -> float:
    """The posterior weight of the other goal given the mean of x_t over `points` points, goals `separation` apart."""
    signal, sigma = np.sqrt(abar) * separation, np.sqrt((1.0 - abar) / points)
    z = rng.normal(0.0, sigma, draws)  # the noise of the mean along the line between the goals
    log_ratio = np.clip(signal * (signal + 2 * z) / (2 * sigma**2), -50, 50)  # log p(own) / p(other)
    return float(np.mean(1.0 / (1.0 + np.exp(log_ratio))))


def mean(values: list) -> float | None:
    kept = [v for v in values if v is not None]
    return float(np.mean(kept)) if kept else None


def from_noised_goal(model, demos: list[dict], steps: list[int], generator, batch: int = 4) -> dict:
    import torch

    from tax3d.data.dataset import make_target
    from tax3d.frames import to_world
    from tax3d.geometry import farthest_point_sample

    diffusion = model.diffusion
    out = {t: {"x0_rmse": [], "toward_other": [], "precision_rmse": []} for t in steps}
    for own in range(len(demos)):
        demo = demos[own]
        action = torch.as_tensor(demo["action_pc"], dtype=torch.float32)
        keep = farthest_point_sample(action, min(model.config.data.num_action_points, len(action)), start=generator)
        frames = model._frames(action[keep], demo["anchor_pc"], generator)
        goals = [np.asarray(d["action_pc"] + d["flow"])[keep.numpy()] for d in demos]
        x0 = make_target(torch.as_tensor(goals[own], dtype=torch.float32)[None],
                         {k: v[None] for k, v in frames.items()}, model.spec).expand(batch, -1, -1)
        fn = model.model_fn(frames["action"][None].expand(batch, -1, -1), frames["anchor"][None].expand(batch, -1, -1))
        for t in steps:
            noise = torch.randn(x0.shape, generator=generator)
            x = diffusion.q_sample(x0, torch.full((batch,), t, dtype=torch.long), noise=noise)
            for i in range(t, -1, -1):
                step = diffusion.p_sample(fn, x, torch.full((batch,), i, dtype=torch.long), generator=generator)
                if i == t:
                    for estimate in to_world(step["pred_xstart"], frames, model.spec).numpy():
                        out[t]["x0_rmse"].append(float(rmse(estimate, goals[own])))
                        if len(goals) == 2:
                            out[t]["toward_other"].append(lean(estimate, goals[own], goals[1 - own]))
                x = step["sample"]
            for final in to_world(x, frames, model.spec).numpy():
                out[t]["precision_rmse"].append(sample_parts(final, goals)["precision_rmse"])
    return out


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("checkpoint", type=Path)
    parser.add_argument("--data", type=Path, required=True, help="a folder of demo_N.npz")
    parser.add_argument("--cloths", type=int, default=20)
    parser.add_argument("--samples", type=int, default=5)
    parser.add_argument("--steps", default="30,45,55,65,75,85,99", help="the noise steps t to start from")
    parser.add_argument("--out", type=Path, default=None, help="write the JSON here too")
    args = parser.parse_args()
    try:
        steps = sorted({int(s) for s in args.steps.split(",")})
    except ValueError:
        steps = []
    problems = [(not (args.checkpoint / "config.json").is_file(),
                 f"checkpoint {args.checkpoint}: no config.json in it; expected a checkpoint folder"),
                (not args.data.is_dir(), f"--data {args.data}: no such folder; expected a folder of demo_N.npz"),
                (args.cloths < 1 or args.samples < 1, "--cloths and --samples: expected at least 1"),
                (not steps, f"--steps {args.steps}: expected comma-separated whole noise steps")]
    for bad, message in problems:
        if bad:
            print(f"error: {message}", file=sys.stderr)
            return 2
    import torch

    from tax3d.data.format import cloth_groups
    from tax3d.model.tax3d import Tax3D

    torch.set_num_threads(1)
    torch.set_grad_enabled(False)
    model = Tax3D.from_pretrained(args.checkpoint).eval()
    T = model.diffusion.num_timesteps
    if steps[0] < 0 or steps[-1] >= T:
        print(f"error: --steps {args.steps}: expected noise steps in [0, {T - 1}]", file=sys.stderr)
        return 2
    groups = [g for g in cloth_groups(args.data) if len(g) <= 2][:args.cloths]
    if not groups:
        print(f"error: --data {args.data}: no demo_N.npz of a cloth with one or two goals", file=sys.stderr)
        return 2
    generator = torch.Generator().manual_seed(SEED)
    rng = np.random.default_rng(SEED)
    parts, noised, lean = [], {t: {} for t in steps}, {t: [] for t in steps}
    points = model.config.data.num_action_points
    for index, demos in enumerate(groups):
        goals = [d["action_pc"] + d["flow"] for d in demos]
        samples = model.predict(demos[0]["action_pc"], demos[0]["anchor_pc"], num_samples=args.samples, seed=index)
        parts += [sample_parts(s, goals) for s in samples]
        for t, values in from_noised_goal(model, demos, steps, generator).items():
            for key, v in values.items():
                noised[t].setdefault(key, []).extend(v)
        if len(goals) == 2:
            separation = float(np.linalg.norm(goals[1].mean(0) - goals[0].mean(0)))
            for t in steps:
                lean[t].append(bayes_lean(separation, float(model.diffusion.alphas_cumprod[t]), points, rng))
    out = {
        "command": "python " + " ".join(sys.argv), "date": provenance.today(), "machine": provenance.machine(),
        "checkpoint": str(args.checkpoint), "cloths": len(groups), "samples_per_cloth": args.samples,
        "samples": {key: mean([p[key] for p in parts]) for key in parts[0]},
        "from_noised_goal": [{"t": t, **{k: mean(v) for k, v in noised[t].items()},
                              "bayes_toward_other": mean(lean[t])} for t in steps],
    }
    print(write_json(args.out, out))
    return 0


if __name__ == "__main__":
    sys.exit(main())
