"""Per-dimension min/max scaling to [-1, 1], fitted on the training data and stored with the weights."""

from __future__ import annotations

import torch
import torch.nn as nn


class MinMaxNormalizer(nn.Module):
    """x -> (x - centre) / half_range per last dimension; a constant dimension maps to 0 (its value minus itself)."""

    def __init__(self, dim: int):
        super().__init__()
        self.register_buffer("low", -torch.ones(dim))
        self.register_buffer("high", torch.ones(dim))

    def fit(self, data: torch.Tensor, rotation_invariant: bool = False) -> "MinMaxNormalizer":
        """Limits from data (..., dim). rotation_invariant: dim is a run of 3-vectors, and each vector's x and y
        get the limits +-max sqrt(x^2 + y^2), so that any rotation about z stays inside [-1, 1]."""
        data = data.reshape(-1, data.shape[-1]).double()
        low, high = data.min(0).values, data.max(0).values
        if rotation_invariant:
            vectors = data.reshape(len(data), -1, 3)  # (S, K, 3)
            radius = vectors[..., :2].norm(dim=-1).max(0).values  # (K,)
            low, high = low.reshape(-1, 3).clone(), high.reshape(-1, 3).clone()
            low[:, :2], high[:, :2] = -radius[:, None], radius[:, None]
            low, high = low.reshape(-1), high.reshape(-1)
        self.low.copy_(low.float())
        self.high.copy_(high.float())
        return self

    def _centre_and_half(self) -> tuple[torch.Tensor, torch.Tensor]:
        half = (self.high - self.low) / 2
        return (self.high + self.low) / 2, torch.where(half < 5e-5, torch.ones_like(half), half)

    def normalize(self, x: torch.Tensor) -> torch.Tensor:
        centre, half = self._centre_and_half()
        return (x - centre) / half

    def unnormalize(self, y: torch.Tensor) -> torch.Tensor:
        centre, half = self._centre_and_half()
        return y * half + centre
