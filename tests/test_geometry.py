import math

import numpy as np
import pytest
import torch

from tax3d.geometry import (centre, farthest_point_sample, fps_loop_numpy, fps_loop_torch, rotate_z,
                            rotation_z)


def clusters(num_clusters=5, per_cluster=20, seed=0):
    gen = torch.Generator().manual_seed(seed)
    centres = torch.tensor([[10.0 * i, 5.0 * (i % 2), 0.0] for i in range(num_clusters)])
    points = centres.repeat_interleave(per_cluster, 0) + 0.01 * torch.randn(num_clusters * per_cluster, 3, generator=gen)
    return points, per_cluster


def test_fps_indices_are_distinct():
    points = torch.randn(200, 3, generator=torch.Generator().manual_seed(1))
    idx = farthest_point_sample(points, 50, start=torch.Generator().manual_seed(2))
    assert idx.shape == (50,) and idx.dtype == torch.long
    assert len(set(idx.tolist())) == 50


def test_fps_picks_one_point_per_cluster_first():
    points, per_cluster = clusters()
    for seed in range(4):
        idx = farthest_point_sample(points, 5, start=torch.Generator().manual_seed(seed))
        assert sorted((idx // per_cluster).tolist()) == [0, 1, 2, 3, 4]


def test_fps_start_and_generator():
    points = torch.randn(100, 3, generator=torch.Generator().manual_seed(3))
    assert farthest_point_sample(points, 10, start=7)[0] == 7
    a = farthest_point_sample(points, 10, start=torch.Generator().manual_seed(5))
    b = farthest_point_sample(points, 10, start=torch.Generator().manual_seed(5))
    assert torch.equal(a, b)


@pytest.mark.parametrize("kind", ["normal", "grid with ties", "cloth-like sheet", "batch"])
def test_fps_numpy_loop_gives_the_torch_loops_indices(kind):
    gen = torch.Generator().manual_seed(11)
    if kind == "normal":
        pts = torch.randn(1, 1300, 3, generator=gen)
    elif kind == "grid with ties":
        pts = torch.randint(0, 4, (1, 600, 3), generator=gen).float()
    elif kind == "cloth-like sheet":
        u, v = torch.meshgrid(torch.linspace(0, 0.4, 25), torch.linspace(0, 0.4, 25), indexing="ij")
        sheet = torch.stack([u, v, 0.01 * torch.sin(10 * u)], -1).reshape(1, -1, 3)
        pts = sheet + 1e-4 * torch.randn(sheet.shape, generator=gen)
    else:
        pts = torch.randn(4, 300, 3, generator=gen)
    pts = (pts - pts.mean(-2, keepdim=True)).float()
    far = torch.randint(pts.shape[1], (pts.shape[0],), generator=gen)
    k = min(512, pts.shape[1] - 1)
    assert torch.equal(fps_loop_numpy(pts, k, far), fps_loop_torch(pts, k, far))


def test_fps_batch_matches_single_clouds():
    points = torch.randn(3, 80, 3, generator=torch.Generator().manual_seed(4))
    batch = farthest_point_sample(points, 12, start=0)
    assert batch.shape == (3, 12)
    for b in range(3):
        assert torch.equal(batch[b], farthest_point_sample(points[b], 12, start=0))
        assert len(set(batch[b].tolist())) == 12


def test_fps_with_k_at_least_n_returns_every_point_then_pads():
    points = torch.randn(6, 3)
    assert torch.equal(farthest_point_sample(points, 6), torch.arange(6))
    idx = farthest_point_sample(points, 10, start=torch.Generator().manual_seed(0))
    assert idx.shape == (10,)
    assert torch.equal(idx[:6], torch.arange(6))
    assert 0 <= idx.min() and idx.max() < 6
    assert farthest_point_sample(points.expand(2, 6, 3), 8).shape == (2, 8)
    with pytest.raises(ValueError):
        farthest_point_sample(points, 0)


def test_rotation_z_matrix():
    r = rotation_z(math.pi / 2)
    assert isinstance(r, np.ndarray)
    np.testing.assert_allclose(r @ np.array([1.0, 0.0, 0.0]), [0.0, 1.0, 0.0], atol=1e-12)
    angles = torch.tensor([0.3, -1.2, 4.0], dtype=torch.float64)
    rt = rotation_z(angles)
    assert rt.shape == (3, 3, 3)
    eye = torch.eye(3, dtype=torch.float64).expand(3, 3, 3)
    torch.testing.assert_close(rt @ rt.transpose(-1, -2), eye)
    np.testing.assert_allclose(np.linalg.det(rt.numpy()), np.ones(3))


def test_rotate_z_keeps_height_and_norm():
    points = torch.randn(2, 30, 3, dtype=torch.float64)
    out = rotate_z(points, torch.tensor([0.7, 2.0], dtype=torch.float64))
    torch.testing.assert_close(out[..., 2], points[..., 2])
    torch.testing.assert_close(out.norm(dim=-1), points.norm(dim=-1))
    torch.testing.assert_close(rotate_z(out[0], -0.7), points[0])
    np.testing.assert_allclose(rotate_z(points[1].numpy(), 2.0), out[1].numpy(), atol=1e-12)


def test_centre():
    points = torch.randn(4, 25, 3, generator=torch.Generator().manual_seed(0)) + torch.tensor([3.0, -2.0, 8.0])
    centred, mean = centre(points)
    assert mean.shape == (4, 3)
    torch.testing.assert_close(centred.mean(-2), torch.zeros(4, 3), atol=1e-5, rtol=0)
    torch.testing.assert_close(centred + mean[:, None], points)
    centred_np, mean_np = centre(points[0].numpy())
    # float32 sums of 25 values near 8 in another order: a few units in the last place (8 * 2^-23 ~ 1e-6) apart
    np.testing.assert_allclose(mean_np, mean[0].numpy(), atol=1e-5)
