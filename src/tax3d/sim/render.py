"""Pictures of an episode: RGB frames from PyBullet's CPU renderer, saved as PNG files or one GIF."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pybullet

FRAME_SIZE = (400, 300)


def render_frame(env, size=FRAME_SIZE) -> np.ndarray:
    """One RGB frame (H, W, 3) of the scene, looking at the cloth and the anchor from the side."""
    goal = env.goal()
    target = (goal + np.array([0.0, 5.0, 7.0])) / 2
    target[2] = 6.5
    spread = np.linalg.norm(goal[:2] - np.array([0.0, 5.0]))
    view = pybullet.computeViewMatrixFromYawPitchRoll(
        target.tolist(), distance=11.0 + 0.8 * spread, yaw=50.0, pitch=-15.0, roll=0.0, upAxisIndex=2
    )
    projection = pybullet.computeProjectionMatrixFOV(fov=50.0, aspect=size[0] / size[1], nearVal=0.1, farVal=200.0)
    _, _, rgba, _, _ = pybullet.getCameraImage(
        size[0], size[1], view, projection, renderer=pybullet.ER_TINY_RENDERER, physicsClientId=env.client
    )
    return np.asarray(rgba, dtype=np.uint8).reshape(size[1], size[0], 4)[:, :, :3]


def save_frames(frames: list[np.ndarray], path: str | os.PathLike, fmt: str) -> Path:
    """fmt 'png': a folder of frame_NNN.png; fmt 'gif': one animated file. Written atomically."""
    from PIL import Image

    path = Path(path)
    images = [Image.fromarray(f) for f in frames]
    if fmt == "gif":
        out = path.with_suffix(".gif")
        out.parent.mkdir(parents=True, exist_ok=True)
        tmp = out.with_name(f".{out.name}.tmp")
        images[0].save(tmp, format="GIF", save_all=True, append_images=images[1:], duration=80, loop=0)
        os.replace(tmp, out)
        return out
    path.mkdir(parents=True, exist_ok=True)
    for i, image in enumerate(images):
        tmp = path / f".frame_{i:03d}.png.tmp"
        image.save(tmp, format="PNG")
        os.replace(tmp, path / f"frame_{i:03d}.png")
    return path
