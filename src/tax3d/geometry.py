"""Point-cloud geometry: farthest point sampling, z-rotations, centring and the anchor pose.

The rigid helpers take numpy arrays or torch tensors and return the same kind; points are rows (..., N, 3).
"""

from __future__ import annotations

import math

import numpy as np
import torch


def farthest_point_sample(
    points: torch.Tensor, k: int, start: int | torch.Generator | None = None
) -> torch.Tensor:
    """Indices (k,) or (B, k) of k farthest points of (N, 3) or (B, N, 3) points.

    The first index is random (from `start` when it is a generator, the global torch generator when None)
    or `start` itself when it is an int. When k >= N every point is returned once, in index order
    (0..N-1, no sampling), followed by k - N indices drawn uniformly with repetition, so that the output
    always has k entries.
    """
    if k < 1:
        raise ValueError(f"k must be at least 1, got {k}")
    squeeze = points.dim() == 2
    pts = points.unsqueeze(0) if squeeze else points
    batch, n, _ = pts.shape
    generator = start if isinstance(start, torch.Generator) else None
    gen_device = generator.device if generator is not None else "cpu"

    if k >= n:
        idx = torch.arange(n).repeat(batch, 1)
        if k > n:
            extra = torch.randint(n, (batch, k - n), generator=generator, device=gen_device).cpu()
            idx = torch.cat([idx, extra], dim=1)
        idx = idx.to(pts.device)
        return idx[0] if squeeze else idx

    if isinstance(start, int):
        far = torch.full((batch,), start, dtype=torch.long)
    else:
        far = torch.randint(n, (batch,), generator=generator, device=gen_device).cpu()
    far = far.to(pts.device)
    # Centred float32 coordinates: the indices only need distances good enough to rank.
    pts = (pts - pts.mean(-2, keepdim=True)).float()
    loop = fps_loop_numpy if pts.device.type == "cpu" else fps_loop_torch
    idx = loop(pts, k, far)
    return idx[0] if squeeze else idx


def fps_loop_torch(pts: torch.Tensor, k: int, far: torch.Tensor) -> torch.Tensor:
    """The FPS loop on (B, N, 3) float32 points from first indices far (B,), batched in torch: the GPU's."""
    batch, n, _ = pts.shape
    rows = torch.arange(batch, device=pts.device)
    chosen = []
    dist = torch.full((batch, n), float("inf"), device=pts.device)
    for _ in range(k):
        chosen.append(far)
        dist = torch.minimum(dist, (pts - pts[rows, far].unsqueeze(1)).square().sum(-1))  # (B, N)
        far = dist.argmax(-1)
    return torch.stack(chosen, -1)


def fps_loop_numpy(pts: torch.Tensor, k: int, far: torch.Tensor) -> torch.Tensor:
    """`fps_loop_torch` on CPU tensors, in numpy and one row at a time: about 4x faster on a CPU, where torch's
    per-operation overhead bounds the data loading of training (benchmarks/fps.py). The squared distances are
    summed x, then y, then z, in float32, as torch's sum over the last axis does, and argmax takes the first
    maximum as torch's does, so the indices are the same (tests/test_geometry.py)."""
    pts, far = pts.numpy(), far.numpy()
    batch, n, _ = pts.shape
    idx = np.empty((batch, k), dtype=np.int64)
    for b in range(batch):
        x, y, z = (np.ascontiguousarray(pts[b, :, axis]) for axis in range(3))
        dist = np.full(n, np.inf, dtype=np.float32)
        step, term = np.empty_like(dist), np.empty_like(dist)
        f, row = int(far[b]), idx[b]
        for j in range(k):
            row[j] = f
            np.subtract(x, x[f], out=step)
            np.multiply(step, step, out=step)
            for c in (y, z):
                np.subtract(c, c[f], out=term)
                np.multiply(term, term, out=term)
                np.add(step, term, out=step)
            np.minimum(dist, step, out=dist)
            f = int(dist.argmax())
    return torch.from_numpy(idx)


def rotation_z(angle):
    """Rotation matrix (..., 3, 3) about +z by `angle` radians (float, numpy array or tensor)."""
    if isinstance(angle, torch.Tensor):
        c, s = torch.cos(angle), torch.sin(angle)
        one, zero = torch.ones_like(c), torch.zeros_like(c)
        rows = [torch.stack([c, -s, zero], -1), torch.stack([s, c, zero], -1), torch.stack([zero, zero, one], -1)]
        return torch.stack(rows, -2)
    angle = np.asarray(angle, dtype=np.float64)
    c, s = np.cos(angle), np.sin(angle)
    one, zero = np.ones_like(c), np.zeros_like(c)
    rows = [np.stack([c, -s, zero], -1), np.stack([s, c, zero], -1), np.stack([zero, zero, one], -1)]
    return np.stack(rows, -2)


def _like(matrix, points):
    """`matrix` converted to the array kind, dtype and device of `points`."""
    if isinstance(points, torch.Tensor):
        return torch.as_tensor(matrix).to(dtype=points.dtype, device=points.device)
    if isinstance(matrix, torch.Tensor):
        matrix = matrix.detach().cpu().numpy()
    return np.asarray(matrix, dtype=np.result_type(points.dtype, np.float32))


def rotate_z(points, angle):
    """Points (..., N, 3) rotated about the z axis through the origin; a batch of angles (B,) needs (B, N, 3)."""
    return points @ _like(rotation_z(angle), points).swapaxes(-1, -2)


def centre(points):
    """(points - mean, mean): the cloud (..., N, 3) moved to its mean, and the mean (..., 3)."""
    mean = points.mean(-2)
    return points - mean[..., None, :], mean


def random_angle(generator: torch.Generator | None = None) -> float:
    """An angle drawn from U(0, 2 pi)."""
    return float(torch.rand((), generator=generator, dtype=torch.float64)) * 2.0 * math.pi


def nearest_rows(points: np.ndarray, targets: np.ndarray) -> list[int]:
    """The row of `points` nearest each target: the observed points a policy takes for the grasped ones."""
    return [int(np.argmin(np.linalg.norm(points - t, axis=1))) for t in np.atleast_2d(targets)]
