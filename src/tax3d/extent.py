"""The extent of point clouds, recorded in a checkpoint from its training demonstrations and compared with the
clouds it is asked to predict for: a cloud FACTOR times larger or smaller than any the network saw (another unit,
another scene) is named in a warning, since the network then predicts far outside what it learned.

The extent of a cloud is the root-mean-square distance of its points from their mean; a checkpoint records the
median over its training demos, for the action and the anchor clouds (config.json's "extent"). Checkpoints written
before the record was kept have none, and are not checked."""

from __future__ import annotations

import warnings

import numpy as np

FACTOR = 3.0
"""an input whose extent is more than FACTOR times, or less than 1 / FACTOR of, the training median is named"""


class ExtentWarning(UserWarning):
    """Input clouds far larger or smaller than the checkpoint's training clouds."""


def spread(points) -> float:
    if hasattr(points, "detach"):  # a tensor, on any device
        points = points.detach().cpu().numpy()
    points = np.asarray(points, dtype=np.float64)
    return float(np.sqrt(((points - points.mean(0)) ** 2).sum(1).mean()))


def of_scenes(scenes) -> dict:
    """{"action": ..., "anchor": ...}: the median extent over (action, anchor) scenes."""
    scenes = list(scenes)
    return {"action": float(np.median([spread(a) for a, _ in scenes])),
            "anchor": float(np.median([spread(b) for _, b in scenes]))}


def mismatch(recorded: dict | None, scenes) -> str | None:
    """The words for the cloud furthest outside the recorded extent by more than FACTOR, or None."""
    if not recorded:
        return None
    worst = None
    for action, anchor in scenes:
        for name, points in (("action", action), ("anchor", anchor)):
            expected = recorded.get(name)
            if not expected or len(points) < 2:
                continue
            ratio = spread(points) / expected
            off = max(ratio, 1 / ratio) if ratio > 0 else float("inf")
            if off > FACTOR and (worst is None or off > worst[0]):
                worst = (off, name, ratio, spread(points), expected)
    if worst is None:
        return None
    _, name, ratio, seen, expected = worst
    return (f"the {name} cloud's extent (RMS distance from its mean) is {seen:.4g}, {ratio:.3g} times the {expected:.4g} "
            f"of the clouds this checkpoint trained on; it expects clouds in its training data's units and size "
            f"(within {FACTOR:g} times), and predicts far outside what it learned otherwise")


def warn(recorded: dict | None, scenes) -> None:
    message = mismatch(recorded, scenes)
    if message is not None:
        warnings.warn(message, ExtentWarning, stacklevel=3)
