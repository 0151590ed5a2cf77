"""DDIM for DP3 (docs/reference.md, "DP3 baseline"): squaredcos_cap_v2 betas, sample prediction, clipping, eta = 0.

The settings DP3 gives its scheduler: 100 training steps, 10 inference steps, steps offset 0 and the last step
to alpha_bar = 1 ("set_alpha_to_one"), so the final step returns the (clipped) predicted clean sample.
"""

from __future__ import annotations

import math
from typing import Callable

import torch


def squaredcos_cap_v2_betas(num_steps: int, max_beta: float = 0.999) -> torch.Tensor:
    """beta_i = min(1 - abar((i + 1) / T) / abar(i / T), max_beta), abar(t) = cos^2((t + 0.008) / 1.008 * pi / 2).

    The cosine schedule of Nichol & Dhariwal (2021), eq. 17, capped as in their paper."""
    def alpha_bar(t: float) -> float:
        return math.cos((t + 0.008) / 1.008 * math.pi / 2) ** 2

    return torch.tensor([min(1 - alpha_bar((i + 1) / num_steps) / alpha_bar(i / num_steps), max_beta)
                         for i in range(num_steps)], dtype=torch.float64)


class DDIM:
    """Forward noising for training and the deterministic DDIM sampler for a network that predicts x_0."""

    def __init__(self, train_steps: int = 100, inference_steps: int = 10, clip_sample: bool = True):
        self.train_steps, self.inference_steps, self.clip_sample = train_steps, inference_steps, clip_sample
        self.betas = squaredcos_cap_v2_betas(train_steps)
        self.alphas_cumprod = torch.cumprod(1.0 - self.betas, 0)  # (T,) float64

    def timesteps(self) -> list[int]:
        """The inference timesteps, high to low: (S - 1) k, ..., k, 0 with k = T // S."""
        stride = self.train_steps // self.inference_steps
        return [i * stride for i in reversed(range(self.inference_steps))]

    def _abar(self, t: torch.Tensor | int, like: torch.Tensor) -> torch.Tensor:
        """alpha_bar_t (1 for t < 0) shaped to broadcast against `like` (B, ...)."""
        t = torch.as_tensor(t)
        abar = torch.where(t >= 0, self.alphas_cumprod[t.clamp(min=0)], torch.ones((), dtype=torch.float64))
        abar = abar.to(device=like.device, dtype=like.dtype)
        return abar.reshape(abar.shape + (1,) * (like.dim() - abar.dim()))

    def add_noise(self, x0: torch.Tensor, noise: torch.Tensor, t: torch.Tensor) -> torch.Tensor:
        """x_t = sqrt(abar_t) x_0 + sqrt(1 - abar_t) eps (DDPM, Ho et al. 2020, eq. 4); t (B,) in [0, T)."""
        abar = self._abar(t.cpu(), x0)
        return abar.sqrt() * x0 + (1 - abar).sqrt() * noise

    def step(self, x0_pred: torch.Tensor, t: int, x_t: torch.Tensor) -> torch.Tensor:
        """x_{t - k} from x_t and the predicted x_0 (Song et al. 2021, eq. 12 with sigma = 0).

        The noise estimate comes from the unclipped x_0, and only the x_0 term is clipped, as in the diffusers
        DDIMScheduler that DP3 runs."""
        abar_t = self._abar(t, x_t)
        abar_prev = self._abar(t - self.train_steps // self.inference_steps, x_t)
        eps = (x_t - abar_t.sqrt() * x0_pred) / (1 - abar_t).sqrt()
        if self.clip_sample:
            x0_pred = x0_pred.clamp(-1.0, 1.0)
        return abar_prev.sqrt() * x0_pred + (1 - abar_prev).sqrt() * eps

    def sample(self, model: Callable[[torch.Tensor, torch.Tensor], torch.Tensor], shape: tuple,
               generator: torch.Generator | None = None, device="cpu") -> torch.Tensor:
        """Denoise x_T ~ N(0, I) of `shape` in `inference_steps` steps; model(x_t, t (B,)) returns x_0."""
        x = torch.randn(shape, generator=generator, device=generator.device if generator else device).to(device)
        for t in self.timesteps():
            x = self.step(model(x, torch.full((shape[0],), t, device=device, dtype=torch.long)), t, x)
        return x
