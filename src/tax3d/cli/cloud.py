"""`tax3d cloud`: one depth image, its mask, intrinsics and camera pose to a world-frame cloud (.npy)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Annotated

import numpy as np

from tax3d.atomic import atomic_write
from tax3d.camera import depth_to_cloud
from tax3d.errors import UsageError
from tax3d.options import Positive


@dataclass
class Args:
    """Turn one depth image into a world-frame point cloud (tax3d.camera.depth_to_cloud; its docstring states the
    conventions), as a .npy file of (N, 3) points."""

    depth: str
    """a .npy depth image (H, W): z-depth along the optical axis"""
    mask: str
    """a .npy boolean image (H, W): the object's pixels, each with a finite, positive depth"""
    intrinsics: str
    """a .npy (3, 3) pinhole matrix [[fx, 0, cx], [0, fy, cy], [0, 0, 1]] in pixels (OpenCV axes)"""
    pose: str
    """a .npy (4, 4) camera-to-world matrix [[R, t], [0, 0, 0, 1]]"""
    out: str
    """the .npy file of the cloud (N, 3), written whole or not at all"""
    depth_scale: Annotated[float, Positive] = 1.0
    """multiplies the depth image first: 0.001 turns millimetres into metres"""


def _load(option: str, path: str) -> np.ndarray:
    try:
        return np.load(path, allow_pickle=False)
    except (OSError, ValueError) as err:
        raise UsageError(f"--{option} {path}: unreadable ({str(err).splitlines()[0]}); expected a .npy array") from None


def _save(path: Path, cloud: np.ndarray) -> None:
    with open(path, "wb") as f:
        np.save(f, cloud, allow_pickle=False)


def run(args: Args) -> int:
    if not Path(args.out).parent.is_dir():
        raise UsageError(f"--out {args.out}: no folder {Path(args.out).parent}; expected a file in an existing folder")
    arrays = {name: _load(name, getattr(args, name)) for name in ("depth", "mask", "intrinsics", "pose")}
    try:
        if arrays["depth"].dtype.kind not in "iuf":
            raise UsageError(f"depth has dtype {arrays['depth'].dtype}; expected numbers")
        cloud = depth_to_cloud(arrays["depth"] * args.depth_scale, arrays["mask"], arrays["intrinsics"],
                               arrays["pose"])
    except UsageError as err:  # name the file the message is about
        name = str(err).split(" ", 1)[0]
        raise UsageError(f"--{name} {getattr(args, name)}: {err}" if name in arrays else str(err)) from None
    atomic_write(args.out, lambda tmp: _save(tmp, cloud))
    print(f"{len(cloud)} points -> {args.out}")
    return 0
