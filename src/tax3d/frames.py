"""Object-specific frames (paper Section 3.1; docs/reference.md, "Model"): a variant's inputs from world points,
and world goal points from a model output.

Anchor frame = anchor points minus the anchor mean, action frame = action points minus the action mean; the goal
is expressed in the anchor frame. The frame origins are kept so that `to_world` maps a model output (a
cross-displacement or goal points, in the variant's frame) back to world-frame goal points.
"""

from __future__ import annotations

import torch

from tax3d.variants import VariantSpec


def frame_inputs(action: torch.Tensor, anchor: torch.Tensor, spec: VariantSpec) -> dict:
    """Action (..., N, 3) and anchor (..., M, 3) world points in the variant's frames, and the frame origins.

    Returns action, anchor (same shapes), action_mean and anchor_mean (..., 3): the world positions of the
    action frame's and the anchor (goal) frame's origins. -W: both zero. SD/SP: both the scene cloud's mean.
    """
    if spec.scene:
        scene_mean = torch.cat([action, anchor], dim=-2).mean(-2)
        action_mean = anchor_mean = scene_mean
    elif spec.object_centric:
        action_mean, anchor_mean = action.mean(-2), anchor.mean(-2)
    else:
        action_mean = action.new_zeros(action.shape[:-2] + (3,))
        anchor_mean = anchor.new_zeros(anchor.shape[:-2] + (3,))
    return {
        "action": action - action_mean[..., None, :],
        "anchor": anchor - anchor_mean[..., None, :],
        "action_mean": action_mean,
        "anchor_mean": anchor_mean,
    }


def to_world(prediction: torch.Tensor, frames: dict, spec: VariantSpec) -> torch.Tensor:
    """World-frame goal action points (..., N, 3) from a model output in the variant's frame.

    `frames` holds action (..., N, 3) and anchor_mean (..., 3) as made by `frame_inputs` or
    `tax3d.data.dataset.make_sample` (a sample or a collated batch); their leading dimensions must broadcast against
    the prediction's, so a single scene's frames serve a stack of samples (S, N, 3). For SD/SP the anchor rows of the prediction
    (after the first N) are dropped.
    """
    action = frames["action"]
    n = action.shape[-2]
    allowed = (n, n + frames["anchor"].shape[-2]) if spec.scene and "anchor" in frames else (n,)
    if prediction.shape[-2] not in allowed:
        raise ValueError(f"prediction has {prediction.shape[-2]} points; expected {' or '.join(map(str, allowed))}")
    goal = prediction[..., :n, :]
    if spec.target == "displacement":
        goal = goal + action
    return goal + frames["anchor_mean"][..., None, :]
