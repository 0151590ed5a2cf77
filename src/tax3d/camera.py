"""A depth camera's image to a world-frame cloud: what a real camera's action or anchor cloud goes through.

Only numpy: no simulator is needed to turn one's own RGB-D frames into the clouds of docs/own-data.md.
"""

from __future__ import annotations

import numpy as np

from tax3d.errors import UsageError


def depth_to_cloud(depth, mask, intrinsics, pose) -> np.ndarray:
    """The world-frame points (N, 3) of the pixels that `mask` selects, in image row order, then column.

    Conventions:
    - `depth` (H, W): the z-depth of each pixel, its distance along the camera's optical axis (not along the pixel's
      ray), in the length unit of the cloud (metres for most cameras' depth images once scaled: a 16-bit image in
      millimetres is divided by 1000 first).
    - `mask` (H, W) of bools: the pixels of the object (a segmentation); every selected pixel must have a finite,
      positive depth, so leave missing measurements (often 0) out of it: `mask & (depth > 0)`.
    - `intrinsics` (3, 3): K = [[fx, 0, cx], [0, fy, cy], [0, 0, 1]] in pixels, the OpenCV pinhole model: the pixel
      of row v and column u has image coordinates (u, v), and its point in the camera's frame is
      z ((u - cx) / fx, (v - cy) / fy, 1), axes x right, y down, z forward (the optical axis).
    - `pose` (4, 4): camera-to-world, p_world = R p_camera + t with [[R, t], [0, 0, 0, 1]], the camera's frame as
      above (OpenCV axes; an OpenGL camera, x right, y up, z backward, is turned by diag(1, -1, -1) first). t is in
      the unit of `depth`.

    Bad input (a depth image that is not 2-D, a mask or matrix of the wrong shape, a mask that selects nothing,
    selected depth that is non-finite or not positive) raises UsageError, a ValueError, in one line, before any work.
    """
    depth, mask, k, pose = _checked(depth, mask, intrinsics, pose)
    v, u = np.nonzero(mask)
    z = depth[v, u]
    camera = np.stack([(u - k[0, 2]) / k[0, 0] * z, (v - k[1, 2]) / k[1, 1] * z, z], axis=1)
    return camera @ pose[:3, :3].T + pose[:3, 3]


def _checked(depth, mask, intrinsics, pose):
    depth = _array("depth", depth)
    if depth.ndim != 2 or 0 in depth.shape:
        raise UsageError(f"depth has shape {depth.shape}; expected a depth image (H, W)")
    mask = np.asarray(mask)
    if mask.shape != depth.shape:
        raise UsageError(f"mask has shape {mask.shape}; expected the depth image's shape {depth.shape}")
    if mask.dtype != bool:
        raise UsageError(f"mask has dtype {mask.dtype}; expected booleans (True: a pixel of the object)")
    k = _array("intrinsics", intrinsics)
    if k.shape != (3, 3) or not np.all(np.isfinite(k)) or not (k[0, 0] > 0 and k[1, 1] > 0):
        raise UsageError(f"intrinsics {k.tolist() if k.size <= 9 else k.shape}; expected a finite (3, 3) matrix "
                         f"[[fx, 0, cx], [0, fy, cy], [0, 0, 1]] with fx, fy > 0")
    pose = _array("pose", pose)
    rigid = pose.shape == (4, 4) and np.all(np.isfinite(pose)) and np.allclose(pose[3], [0, 0, 0, 1])
    if not (rigid and np.allclose(pose[:3, :3] @ pose[:3, :3].T, np.eye(3), atol=1e-5)):
        got = f"shape {pose.shape}" if pose.shape != (4, 4) else "a matrix that is not a rigid transform"
        raise UsageError(f"pose has {got}; expected a finite camera-to-world (4, 4) matrix [[R, t], [0, 0, 0, 1]] "
                         f"with R a rotation")
    selected = int(mask.sum())
    if selected == 0:
        raise UsageError(f"mask selects no pixel of the {depth.shape[0]} x {depth.shape[1]} image; expected at "
                         f"least one pixel of the object")
    z = depth[mask]
    bad = int((~np.isfinite(z)).sum())
    if bad:
        raise UsageError(f"depth is NaN or infinite at {bad} of the {selected} pixels the mask selects; expected "
                         f"finite depth there (leave missing pixels out of the mask)")
    bad = int((z <= 0).sum())
    if bad:
        raise UsageError(f"depth is 0 or negative at {bad} of the {selected} pixels the mask selects; expected "
                         f"positive depth there (leave missing pixels out of the mask: mask & (depth > 0))")
    return depth, mask, k, pose


def _array(name: str, value) -> np.ndarray:
    try:
        return np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise UsageError(f"{name} is not an array of numbers; expected a numeric array") from None
