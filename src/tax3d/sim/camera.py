"""The anchor point cloud: one depth + segmentation render with the reference camera, unprojected to 3D."""

from __future__ import annotations

import functools

import numpy as np
import pybullet

from tax3d.sim.anchor import add_floor, load_anchor, pose_points

# docs/reference.md, "HangProcCloth scene": the authors' camera, column-major, 200 x 200, tiny renderer.
VIEW = [
    0.034899137914180756, 0.1009947806596756, -0.9942747354507446, 0.0,
    -0.9993908405303955, 0.0035267791245132685, -0.03472048044204712, 0.0,
    0.0, 0.9948807954788208, 0.10105633735656738, 0.0,
    4.000894546508789, -5.313570022583008, -7.343255996704102, 1.0,
]  # fmt: skip
PROJECTION = [
    0.7499999403953552, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0,
    0.0, 0.0, -1.0000200271606445, -1.0, 0.0, 0.0, -0.02000020071864128, 0.0,
]  # fmt: skip
IMAGE_SIZE = 200


def depth_to_points(depth: np.ndarray, view=VIEW, projection=PROJECTION) -> np.ndarray:
    """Unproject an OpenGL depth buffer (H, W) to world points (H, W, 3), corner grid, no half-pixel offset."""
    h, w = depth.shape
    y, x = np.mgrid[-1 : 1 : 2 / h, -1 : 1 : 2 / w]
    ndc = np.stack([x, -y, 2 * depth - 1, np.ones_like(depth)], axis=-1).reshape(-1, 4)
    pv = np.asarray(projection).reshape(4, 4, order="F") @ np.asarray(view).reshape(4, 4, order="F")
    points = ndc @ np.linalg.inv(pv).T
    return (points[:, :3] / points[:, 3:]).reshape(h, w, 3)


def opengl_camera(view=VIEW, projection=PROJECTION, width: int = IMAGE_SIZE, height: int = IMAGE_SIZE):
    """The intrinsics K (3, 3) and the camera-to-world pose (4, 4), OpenCV axes, of an OpenGL camera: what
    tax3d.camera.depth_to_cloud takes, so that it unprojects this camera's images as depth_to_points does.

    depth_to_points takes pixel corners, with no half-pixel shift, so the principal point is (W/2, H/2) rather than
    the pixel centres' (W/2 - 1/2, H/2 - 1/2). OpenGL's eye frame (x right, y up, z backward) becomes OpenCV's
    (x right, y down, z forward) by diag(1, -1, -1).
    """
    p = np.asarray(projection, dtype=np.float64).reshape(4, 4, order="F")
    if not np.allclose(p[3], [0, 0, -1, 0]):
        raise ValueError(f"projection's last row is {p[3].tolist()}; expected a perspective projection [0, 0, -1, 0]")
    k = np.array([[p[0, 0] * width / 2, 0.0, width / 2 * (1 - p[0, 2])],
                  [0.0, p[1, 1] * height / 2, height / 2 * (1 + p[1, 2])],
                  [0.0, 0.0, 1.0]])  # fmt: skip
    world_to_eye = np.asarray(view, dtype=np.float64).reshape(4, 4, order="F")
    pose = np.linalg.inv(world_to_eye) @ np.diag([1.0, -1.0, -1.0, 1.0])
    return k, pose


def opengl_depth(buffer: np.ndarray, projection=PROJECTION) -> np.ndarray:
    """The z-depth (distance along the optical axis, scene units) of an OpenGL depth buffer with values in [0, 1].

    From the projection: NDC z = 2 buffer - 1 = -P22 - P23 / z_eye, and the depth is -z_eye."""
    p = np.asarray(projection, dtype=np.float64).reshape(4, 4, order="F")
    return p[2, 3] / (2 * np.asarray(buffer, dtype=np.float64) - 1 + p[2, 2])


def render_image(client: int, view=VIEW, projection=PROJECTION, size: int = IMAGE_SIZE):
    """One tiny-renderer frame of the scene: its depth buffer (H, W) in [0, 1] and its segmentation (H, W), each
    pixel the id of the body seen there (-1: nothing; soft bodies have their ids too)."""
    _, _, _, depth, seg = pybullet.getCameraImage(
        size, size, viewMatrix=list(view), projectionMatrix=list(projection), shadow=0,
        renderer=pybullet.ER_TINY_RENDERER, physicsClientId=client,
    )  # fmt: skip
    return np.asarray(depth, dtype=np.float64).reshape(size, size), np.asarray(seg).reshape(size, size)


def render_segmented_points(client: int, body_ids, size: int = IMAGE_SIZE) -> np.ndarray:
    """World points of the pixels whose segment is one of body_ids, ordered by image column, then row."""
    depth, seg = render_image(client, size=size)
    points = depth_to_points(depth)
    keep = np.isin(seg, list(body_ids))
    return points.transpose(1, 0, 2)[keep.T]


def render_canonical(load_bodies, with_floor: bool) -> np.ndarray:
    """The bodies that load_bodies(client) creates at rot = 0, trans = 0, rendered alone (read-only points)."""
    client = pybullet.connect(pybullet.DIRECT)
    try:
        if with_floor:
            add_floor(client)
        points = render_segmented_points(client, load_bodies(client))
    finally:
        pybullet.disconnect(client)
    points.setflags(write=False)
    return points


@functools.lru_cache(maxsize=4)
def canonical_anchor_cloud(with_floor: bool) -> np.ndarray:
    """The hanger and rod rendered once at rot = 0, trans = 0.

    docs/reference.md, HangProcCloth scene: the camera moves with the anchor.
    """
    return render_canonical(load_anchor, with_floor)


def anchor_cloud(rot_z: float, trans, with_floor: bool = True) -> np.ndarray:
    """The anchor cloud under a random pose: the canonical render moved by p -> Rz p + trans."""
    return pose_points(canonical_anchor_cloud(with_floor), rot_z, trans)
