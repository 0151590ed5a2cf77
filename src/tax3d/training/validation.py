"""TAX3D's validation: the RMSE of predicted goal clouds on the val demos (and, where demos share an observation,
coverage and precision, appendix C)."""

from __future__ import annotations

import numpy as np

from tax3d import config as cfg
from tax3d.data.dataset import demo_files
from tax3d.data.format import grip_vertices, load_demo
from tax3d.metrics import coverage_rmse, grip_error, min_of_samples_rmse, precision_rmse, rmse
from tax3d.model.tax3d import Tax3D


def load_val_demos(config: cfg.Config) -> list[dict]:
    if not config.data.val:
        return []
    files = demo_files(config.data.val)
    if config.train.val_demos > 0:
        files = files[: config.train.val_demos]
    return [load_demo(path) for path in files]


def validate(model: Tax3D, demos: list[dict], num_samples: int, seed: int, steps: int | None = None,
             points: str = "whole") -> dict:
    """World-frame RMSE on whole action clouds: the mean over demos of the min over samples, and over all samples;
    val_grip_error: the mean over demos and samples of the distance at the grasped vertices (where the policy's
    grippers go); where demos share an observation (one per mode), also the coverage and precision RMSE over those
    groups (appendix C)."""
    was_training = model.training
    model.eval()
    scenes = [(d["action_pc"], d["anchor_pc"]) for d in demos]
    predictions = model.predict_scenes(scenes, num_samples=num_samples, steps=steps, seed=seed,
                                       max_points=0 if points == "whole" else None)
    model.train(was_training)
    goals = [d["action_pc"] + d["flow"] for d in demos]
    best = [float(min_of_samples_rmse(p, g)) for p, g in zip(predictions, goals)]
    every = [float(rmse(p, g).mean()) for p, g in zip(predictions, goals)]
    record = {"val_rmse": float(np.mean(best)), "val_rmse_mean": float(np.mean(every))}
    grip = [grip_vertices(d) for d in demos]
    if all(grip):
        record["val_grip_error"] = float(np.mean([grip_error(p, g, v) for p, g, v in zip(predictions, goals, grip)]))
    groups = scene_groups(scenes)
    if any(len(g) > 1 for g in groups):
        pooled = [(np.concatenate([predictions[i] for i in g]), np.stack([goals[i] for i in g])) for g in groups]
        record["val_coverage_rmse"] = float(np.mean([coverage_rmse(p, g) for p, g in pooled]))
        record["val_precision_rmse"] = float(np.mean([precision_rmse(p, g) for p, g in pooled]))
    return record


def scene_groups(scenes: list[tuple[np.ndarray, np.ndarray]]) -> list[list[int]]:
    """Indices of the demos that share one observation (a multimodal cloth's demo for each hole), in first order."""
    groups: dict[bytes, list[int]] = {}
    for i, (action, anchor) in enumerate(scenes):
        key = np.ascontiguousarray(action).tobytes() + b"|" + np.ascontiguousarray(anchor).tobytes()
        groups.setdefault(key, []).append(i)
    return list(groups.values())
