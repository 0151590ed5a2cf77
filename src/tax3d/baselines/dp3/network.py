"""DP3's networks (docs/reference.md, "DP3 baseline"): the point-cloud and state encoder, and the conditional
1-D UNet.
"""

from __future__ import annotations

import math

import torch
import torch.nn as nn


def mlp(dims: tuple[int, ...], layer_norm: bool, last_activation: bool) -> nn.Sequential:
    """Linear layers between consecutive dims, each followed by (LayerNorm and) ReLU, the last one optionally."""
    layers: list[nn.Module] = []
    for i, (a, b) in enumerate(zip(dims[:-1], dims[1:])):
        layers.append(nn.Linear(a, b))
        if last_activation or i < len(dims) - 2:
            layers += [nn.LayerNorm(b), nn.ReLU()] if layer_norm else [nn.ReLU()]
    return nn.Sequential(*layers)


class ObservationEncoder(nn.Module):
    """DP3 encoder: per-point MLP 3-64-128-256 (LayerNorm + ReLU), max-pool, Linear + LayerNorm; state MLP."""

    def __init__(self, state_dim: int, point_dims=(64, 128, 256), out_dim: int = 64, state_dims=(64, 64)):
        super().__init__()
        self.points = mlp((3, *point_dims), layer_norm=True, last_activation=True)
        self.project = nn.Sequential(nn.Linear(point_dims[-1], out_dim), nn.LayerNorm(out_dim))
        self.state = mlp((state_dim, *state_dims), layer_norm=False, last_activation=False)
        self.out_dim = out_dim + state_dims[-1]

    def forward(self, points: torch.Tensor, state: torch.Tensor) -> torch.Tensor:
        """points (B, N, 3), state (B, S) -> features (B, out_dim)."""
        features = self.points(points).max(dim=1).values  # (B, 256)
        return torch.cat([self.project(features), self.state(state)], dim=-1)  # (B, 64 + 64)


class StepEmbedding(nn.Module):
    """Sinusoidal embedding of the diffusion step (Vaswani et al. 2017), then Linear-Mish-Linear."""

    def __init__(self, dim: int):
        super().__init__()
        self.dim = dim
        self.mlp = nn.Sequential(nn.Linear(dim, 4 * dim), nn.Mish(), nn.Linear(4 * dim, dim))

    def forward(self, t: torch.Tensor) -> torch.Tensor:
        half = self.dim // 2
        freqs = torch.exp(-math.log(10000.0) * torch.arange(half, device=t.device) / (half - 1))
        angles = t.float()[:, None] * freqs[None]  # (B, dim / 2)
        return self.mlp(torch.cat([angles.sin(), angles.cos()], dim=-1))  # (B, dim)


class ConvBlock(nn.Sequential):
    """Conv1d, GroupNorm, Mish."""

    def __init__(self, c_in: int, c_out: int, kernel_size: int, groups: int):
        super().__init__(nn.Conv1d(c_in, c_out, kernel_size, padding=kernel_size // 2), nn.GroupNorm(groups, c_out),
                         nn.Mish())


class FiLMResidualBlock(nn.Module):
    """Two conv blocks; the condition sets a per-channel scale and bias between them (FiLM, Perez et al. 2018)."""

    def __init__(self, c_in: int, c_out: int, cond_dim: int, kernel_size: int, groups: int):
        super().__init__()
        self.block1 = ConvBlock(c_in, c_out, kernel_size, groups)
        self.block2 = ConvBlock(c_out, c_out, kernel_size, groups)
        self.film = nn.Sequential(nn.Mish(), nn.Linear(cond_dim, 2 * c_out))
        self.skip = nn.Conv1d(c_in, c_out, 1) if c_in != c_out else nn.Identity()

    def forward(self, x: torch.Tensor, cond: torch.Tensor) -> torch.Tensor:
        scale, bias = self.film(cond)[..., None].chunk(2, dim=1)  # (B, C, 1) each
        h = scale * self.block1(x) + bias  # (B, C, L)
        return self.block2(h) + self.skip(x)


class ConditionalUnet1D(nn.Module):
    """A temporal UNet over the action sequence (Chi et al. 2023, as DP3 uses it): FiLM on every residual block.

    Each level but the last halves the sequence length; the way up joins the skips of the two deepest levels,
    as in Diffusion Policy's network."""

    def __init__(self, action_dim: int, global_dim: int, down_dims=(512, 1024, 2048), step_embed_dim: int = 128,
                 kernel_size: int = 5, groups: int = 8):
        super().__init__()
        self.step_embed = StepEmbedding(step_embed_dim)
        cond = step_embed_dim + global_dim
        block = lambda a, b: FiLMResidualBlock(a, b, cond, kernel_size, groups)
        widths = [action_dim, *down_dims]
        pairs = list(zip(widths[:-1], widths[1:]))
        self.down = nn.ModuleList(
            nn.ModuleList([block(a, b), block(b, b),
                           nn.Conv1d(b, b, 3, stride=2, padding=1) if i < len(pairs) - 1 else nn.Identity()])
            for i, (a, b) in enumerate(pairs))
        self.mid = nn.ModuleList([block(down_dims[-1], down_dims[-1]), block(down_dims[-1], down_dims[-1])])
        self.up = nn.ModuleList(
            nn.ModuleList([block(2 * b, a), block(a, a), nn.ConvTranspose1d(a, a, 4, stride=2, padding=1)])
            for a, b in reversed(pairs[1:]))
        self.final = nn.Sequential(ConvBlock(down_dims[0], down_dims[0], kernel_size, groups),
                                   nn.Conv1d(down_dims[0], action_dim, 1))

    def forward(self, x: torch.Tensor, t: torch.Tensor, global_cond: torch.Tensor) -> torch.Tensor:
        """x (B, H, A) noisy actions, t (B,) diffusion steps, global_cond (B, G) -> (B, H, A)."""
        cond = torch.cat([self.step_embed(t), global_cond], dim=-1)  # (B, E + G)
        h = x.transpose(1, 2)  # (B, A, H)
        skips = []
        for first, second, down in self.down:
            h = second(first(h, cond), cond)
            skips.append(h)
            h = down(h)
        for block in self.mid:
            h = block(h, cond)
        for first, second, up in self.up:
            h = torch.cat([h, skips.pop()], dim=1)  # (B, 2 C, L)
            h = up(second(first(h, cond), cond))
        return self.final(h).transpose(1, 2)  # (B, H, A)
