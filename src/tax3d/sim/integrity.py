"""Did the bag stay a bag? Figures for explosions (edge stretch, spread) and tunnelling (depth inside the hook)."""

from __future__ import annotations

import numpy as np

from tax3d.sim.hook import penetration

# Bounds, well above what the expert's episodes give (docs/hangbag.md): a hung bag stretches its most loaded strap
# edges up to ~1.9x and grows its bounding box to ~1.55x; no vertex was found inside the hook or the pole.
MAX_STRETCH = 3.0  # longest edge / its rest length
MAX_SPREAD = 2.0  # bounding-box diagonal / the rest bag's
MAX_PENETRATION = 0.05  # world units inside a cylinder of the hook or the pole


def mesh_edges(faces: np.ndarray) -> np.ndarray:
    """(E, 2) unique undirected edges of a triangle mesh."""
    faces = np.asarray(faces)
    pairs = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    return np.unique(np.sort(pairs, axis=1), axis=0)


def bag_figures(vertices: np.ndarray, rest: np.ndarray, faces: np.ndarray, rot_z: float, trans) -> dict:
    """Edge stretch and spread against the rest mesh, and the deepest vertex inside the hook or the pole."""
    vertices, rest = np.asarray(vertices), np.asarray(rest)
    edges = mesh_edges(faces)
    length = np.linalg.norm(vertices[edges[:, 0]] - vertices[edges[:, 1]], axis=1)
    rest_length = np.linalg.norm(rest[edges[:, 0]] - rest[edges[:, 1]], axis=1)
    return {
        "stretch": float((length / rest_length).max()),
        "spread": float(np.linalg.norm(np.ptp(vertices, axis=0)) / np.linalg.norm(np.ptp(rest, axis=0))),
        "penetration": float(penetration(vertices, rot_z, trans).max()),
    }


def intact(figures: dict) -> bool:
    """Finite figures within the bounds: no explosion and no tunnelling through the hook or the pole."""
    values = np.array([figures["stretch"], figures["spread"], figures["penetration"]])
    return bool(
        np.all(np.isfinite(values))
        and figures["stretch"] <= MAX_STRETCH
        and figures["spread"] <= MAX_SPREAD
        and figures["penetration"] <= MAX_PENETRATION
    )
