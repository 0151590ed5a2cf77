"""The success checks of appendix A.4.2: HangProcCloth (centroid, then polygon) and HangBag (centroid, twice)."""

from __future__ import annotations

import numpy as np
import shapely

# Thresholds of appendix A.4.2.
CLOTH_CENTROID_THRESHOLD = 1.3
BAG_CENTROID_THRESHOLD = 1.4


def loop_centroid(cloth: np.ndarray, loop: np.ndarray) -> np.ndarray:
    return np.asarray(cloth)[np.asarray(loop)].mean(axis=0)


def centroid_check(cloth: np.ndarray, loop: np.ndarray, goal: np.ndarray, threshold: float) -> bool:
    return bool(np.linalg.norm(loop_centroid(cloth, loop) - np.asarray(goal)) <= threshold)


def polygon_check(cloth: np.ndarray, loop: np.ndarray, goal: np.ndarray) -> bool:
    """Is the goal's xy inside the xy polygon of the ordered loop vertices (repaired if it self-intersects)?"""
    ring = np.asarray(cloth)[np.asarray(loop)][:, :2]
    polygon = shapely.Polygon(ring)
    if not polygon.is_valid:
        polygon = shapely.make_valid(polygon)
    return bool(polygon.contains(shapely.Point(float(goal[0]), float(goal[1]))))


def cloth_success(pre: np.ndarray, post: np.ndarray, loops, goal, threshold=CLOTH_CENTROID_THRESHOLD) -> dict:
    """HangProcCloth: one hole that passes the centroid check on `pre` and the polygon check on `post`."""
    holes = [
        {"centroid": centroid_check(pre, loop, goal, threshold), "polygon": polygon_check(post, loop, goal)}
        for loop in loops
    ]
    return {"success": any(h["centroid"] and h["polygon"] for h in holes), "holes": holes}


def bag_success(pre: np.ndarray, post: np.ndarray, handles, goal, threshold=BAG_CENTROID_THRESHOLD) -> dict:
    """HangBag: one handle whose centroid is within the threshold of the goal both before and after release."""
    parts = [
        {"before": centroid_check(pre, handle, goal, threshold), "after": centroid_check(post, handle, goal, threshold)}
        for handle in handles
    ]
    return {"success": any(h["before"] and h["after"] for h in parts), "handles": parts}
