"""tax3d.camera.depth_to_cloud: a real camera's path from a depth image to a world-frame cloud, checked against the
simulator's own unprojection, and its one-line errors on bad input."""

from __future__ import annotations

import numpy as np
import pybullet
import pytest

from tax3d.camera import depth_to_cloud
from tax3d.errors import UsageError
from tax3d.sim.anchor import add_floor, load_anchor
from tax3d.sim.camera import (
    IMAGE_SIZE, PROJECTION, VIEW, depth_to_points, opengl_camera, opengl_depth, render_image,
    render_segmented_points,
)  # fmt: skip


@pytest.fixture(scope="module")
def anchor_frame():
    """The reference camera's depth buffer and segmentation of the hanger and rod on the floor, and their ids."""
    client = pybullet.connect(pybullet.DIRECT)
    try:
        add_floor(client)
        ids = load_anchor(client)
        depth, seg = render_image(client)
        cloud = render_segmented_points(client, ids)
    finally:
        pybullet.disconnect(client)
    return depth, seg, ids, cloud


def test_the_reference_camera_gives_the_simulators_own_cloud_back(anchor_frame):
    buffer, seg, ids, cloud = anchor_frame
    mask = np.isin(seg, ids)
    k, pose = opengl_camera(VIEW, PROJECTION, IMAGE_SIZE, IMAGE_SIZE)
    points = depth_to_cloud(opengl_depth(buffer), mask, k, pose)
    assert len(points) == len(cloud) == mask.sum() > 500
    np.testing.assert_allclose(points, depth_to_points(buffer)[mask], atol=1e-6)  # row order, pixel for pixel
    # render_segmented_points orders by column, then row: the same points, in another order
    by_column = np.lexsort((points[:, 0], points[:, 1], points[:, 2]))
    np.testing.assert_allclose(points[by_column], cloud[np.lexsort((cloud[:, 0], cloud[:, 1], cloud[:, 2]))],
                               atol=1e-6)


def test_the_pose_is_the_cameras_place_and_axes(anchor_frame):
    buffer, seg, ids, cloud = anchor_frame
    k, pose = opengl_camera()
    # every point of the anchor lies in front of the camera (z forward) and within its view
    camera = (cloud - pose[:3, 3]) @ pose[:3, :3]
    assert camera[:, 2].min() > 0
    pixels = camera @ k.T
    assert np.all((pixels[:, :2] / pixels[:, 2:] >= 0) & (pixels[:, :2] / pixels[:, 2:] <= IMAGE_SIZE))
    # image y (down) points down in the world (z up)
    assert pose[2, 1] < -0.9
    # one pixel's point projects back to that pixel
    mask = np.zeros_like(seg, dtype=bool)
    v, u = np.argwhere(np.isin(seg, ids))[7]
    mask[v, u] = True
    point = depth_to_cloud(opengl_depth(buffer), mask, k, pose)[0]
    camera = np.linalg.inv(pose) @ np.append(point, 1.0)
    np.testing.assert_allclose(k @ (camera[:3] / camera[2]), [u, v, 1.0], atol=1e-6)


def test_depth_is_the_distance_along_the_optical_axis():
    k = np.array([[100.0, 0.0, 2.0], [0.0, 100.0, 1.5], [0.0, 0.0, 1.0]])
    pose = np.eye(4)
    pose[:3, 3] = [1.0, 2.0, 3.0]
    depth = np.full((3, 4), 2.0)
    mask = np.zeros((3, 4), dtype=bool)
    mask[1, 3] = mask[0, 0] = True
    points = depth_to_cloud(depth, mask, k, pose)
    # row 0 first: (u, v) = (0, 0), then (3, 1)
    np.testing.assert_allclose(points, [[1 - 0.04, 2 - 0.03, 5.0], [1 + 0.02, 2 - 0.01, 5.0]])


GOOD_K = np.array([[100.0, 0.0, 2.0], [0.0, 100.0, 1.5], [0.0, 0.0, 1.0]])


@pytest.mark.parametrize(
    "depth, mask, k, pose, expected",
    [
        (np.ones((3, 4, 1)), np.ones((3, 4), bool), GOOD_K, np.eye(4), "depth has shape (3, 4, 1); expected a depth image (H, W)"),
        (np.ones(12), np.ones(12, bool), GOOD_K, np.eye(4), "depth has shape (12,)"),
        (np.ones((3, 4)), np.ones((4, 3), bool), GOOD_K, np.eye(4), "mask has shape (4, 3); expected the depth image's shape (3, 4)"),
        (np.ones((3, 4)), np.ones((3, 4)), GOOD_K, np.eye(4), "mask has dtype float64; expected booleans"),
        (np.ones((3, 4)), np.zeros((3, 4), bool), GOOD_K, np.eye(4), "mask selects no pixel of the 3 x 4 image"),
        (np.full((3, 4), np.nan), np.ones((3, 4), bool), GOOD_K, np.eye(4), "depth is NaN or infinite at 12 of the 12"),
        (np.where(np.eye(3, 4) > 0, np.inf, 1.0), np.ones((3, 4), bool), GOOD_K, np.eye(4), "NaN or infinite at 3 of"),
        (np.zeros((3, 4)), np.ones((3, 4), bool), GOOD_K, np.eye(4), "depth is 0 or negative at 12 of the 12"),
        (np.ones((3, 4)), np.ones((3, 4), bool), np.eye(4), np.eye(4), "intrinsics (4, 4); expected a finite (3, 3)"),
        (np.ones((3, 4)), np.ones((3, 4), bool), GOOD_K, np.eye(3), "pose has shape (3, 3); expected"),
        (np.ones((3, 4)), np.ones((3, 4), bool), GOOD_K, 2 * np.eye(4), "pose has a matrix that is not a rigid"),
        ("deep", np.ones((3, 4), bool), GOOD_K, np.eye(4), "depth is not an array of numbers"),
    ],
)
def test_bad_input_is_one_line(depth, mask, k, pose, expected):
    with pytest.raises(UsageError) as err:
        depth_to_cloud(depth, mask, k, pose)
    assert expected in str(err.value) and "\n" not in str(err.value)


def test_non_finite_depth_outside_the_mask_is_fine():
    depth = np.full((3, 4), np.nan)
    depth[1, 2] = 2.0
    mask = np.zeros((3, 4), dtype=bool)
    mask[1, 2] = True
    assert depth_to_cloud(depth, mask, GOOD_K, np.eye(4)).shape == (1, 3)



def _saved(folder, **arrays) -> dict:
    paths = {}
    for name, value in arrays.items():
        paths[name] = str(folder / f"{name}.npy")
        np.save(paths[name], value)
    return paths


def test_the_cloud_command_writes_the_functions_cloud(tmp_path, capsys):
    from tax3d.cli import main

    depth = np.full((3, 4), 2000.0)  # millimetres
    mask = np.zeros((3, 4), dtype=bool)
    mask[1, 3] = mask[0, 0] = True
    paths = _saved(tmp_path, depth=depth, mask=mask, intrinsics=GOOD_K, pose=np.eye(4))
    out = tmp_path / "cloud.npy"
    assert main(["cloud", *(f"--{k}={v}" for k, v in paths.items()), "--out", str(out), "--depth-scale", "0.001"]) == 0
    np.testing.assert_allclose(np.load(out), depth_to_cloud(depth / 1000, mask, GOOD_K, np.eye(4)))
    assert "2 points" in capsys.readouterr().out


@pytest.mark.parametrize("change, says", [
    (dict(depth=np.ones((3, 4, 1))), "--depth {depth}: depth has shape (3, 4, 1)"),
    (dict(mask=np.zeros((3, 4), bool)), "--mask {mask}: mask selects no pixel"),
    (dict(depth=np.full((3, 4), np.nan)), "--depth {depth}: depth is NaN or infinite at 12 of the 12"),
    (dict(pose="missing"), "--pose {pose}: unreadable"),
])
def test_the_cloud_command_refuses_bad_input_in_one_line(tmp_path, capsys, change, says):
    from tax3d.cli import main

    arrays = {"depth": np.ones((3, 4)), "mask": np.ones((3, 4), bool), "intrinsics": GOOD_K, "pose": np.eye(4)}
    arrays.update({k: v for k, v in change.items() if not isinstance(v, str)})
    paths = _saved(tmp_path, **arrays)
    paths.update({k: str(tmp_path / v) for k, v in change.items() if isinstance(v, str)})
    assert main(["cloud", *(f"--{k}={v}" for k, v in paths.items()), "--out", str(tmp_path / "c.npy")]) == 2
    err = capsys.readouterr().err.strip()
    assert says.format(**paths) in err and len(err.splitlines()) == 1
    assert not (tmp_path / "c.npy").exists()
