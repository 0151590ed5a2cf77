"""Gaussian diffusion for TAX3D (Improved DDPM, as in the DiT code base): schedule, hybrid loss, samplers, respacing.

Paper Sec. 3 (Eq. 1) and App. B; docs/reference.md, "Diffusion". Tensors are channel-last, (B, N, C): the network
outputs (B, N, 2C) with epsilon in the first C channels and the variance interpolation v in the last C when the
variance is learned, else (B, N, C). Schedule buffers are float64 numpy arrays, cast to the data's dtype on use.
"""

from __future__ import annotations

import math
from typing import Callable, Iterator, Sequence

import numpy as np
import torch

ModelFn = Callable[[torch.Tensor, torch.Tensor], torch.Tensor]
LOSSES = ("epsilon", "x0", "v")


#################################################################################
#                          Schedules and respacing                              #
#################################################################################


def linear_betas(num_timesteps: int) -> np.ndarray:
    """Linear schedule of Ho et al. scaled by 1000 / T (docs/reference.md, Diffusion): T = 100 gives 0.001 .. 0.2."""
    scale = 1000.0 / num_timesteps
    return np.linspace(scale * 1e-4, scale * 0.02, num_timesteps, dtype=np.float64)


def space_timesteps(num_timesteps: int, num_steps: int) -> list[int]:
    """num_steps evenly spaced indices of range(num_timesteps), always including the last one (and 0 when
    num_steps > 1); one step keeps T - 1 only, which then predicts x_0 straight from noise."""
    if not 1 <= num_steps <= num_timesteps:
        raise ValueError(f"num_steps must lie in [1, {num_timesteps}], got {num_steps}")
    if num_steps == 1:
        return [num_timesteps - 1]
    stride = (num_timesteps - 1) / (num_steps - 1)
    return sorted({int(round(i * stride)) for i in range(num_steps)})


#################################################################################
#                          Gaussian log-likelihoods                             #
#################################################################################


def normal_kl(mean1, logvar1, mean2, logvar2) -> torch.Tensor:
    """Element-wise KL(N(mean1, exp logvar1) || N(mean2, exp logvar2)) in nats."""
    return 0.5 * (-1.0 + logvar2 - logvar1 + torch.exp(logvar1 - logvar2) + (mean1 - mean2) ** 2 * torch.exp(-logvar2))


def approx_standard_normal_cdf(x: torch.Tensor) -> torch.Tensor:
    # tanh approximation of the standard normal CDF, as in improved-diffusion
    return 0.5 * (1.0 + torch.tanh(math.sqrt(2.0 / math.pi) * (x + 0.044715 * x**3)))


def discretized_gaussian_log_likelihood(x: torch.Tensor, means: torch.Tensor, log_scales: torch.Tensor) -> torch.Tensor:
    """Element-wise log-likelihood (nats) of x under a Gaussian discretised into bins of width 2/255.

    This is improved-diffusion's decoder for 8-bit images in [-1, 1]: values <= -0.999 and >= 0.999 get the whole
    lower / upper tail. The DiT code base the paper builds on uses it unchanged for every kind of data, so it is
    used here for point displacements in DEDO units too (most values then fall in a tail bin); it only enters the
    loss at t == 0, where it trains the variance channels (docs/reference.md, Diffusion).
    """
    centered = x - means
    inv_std = torch.exp(-log_scales)
    cdf_plus = approx_standard_normal_cdf(inv_std * (centered + 1.0 / 255.0))
    cdf_min = approx_standard_normal_cdf(inv_std * (centered - 1.0 / 255.0))
    log_cdf_plus = torch.log(cdf_plus.clamp(min=1e-12))
    log_one_minus_cdf_min = torch.log((1.0 - cdf_min).clamp(min=1e-12))
    log_cdf_delta = torch.log((cdf_plus - cdf_min).clamp(min=1e-12))
    return torch.where(x < -0.999, log_cdf_plus, torch.where(x > 0.999, log_one_minus_cdf_min, log_cdf_delta))


def mean_flat(x: torch.Tensor) -> torch.Tensor:
    """Mean over all but the batch dimension: (B, ...) -> (B,)."""
    return x.reshape(x.shape[0], -1).mean(dim=1)


def point_mean(x: torch.Tensor, weight: torch.Tensor | None) -> torch.Tensor:
    """(B, N, C) -> (B,): the mean over channels, then over points weighted by `weight` (B, N) (None: uniform)."""
    if weight is None:
        return mean_flat(x)
    weight = weight.to(x.dtype)
    return (x.mean(-1) * weight).sum(-1) / weight.sum(-1)


#################################################################################
#                                 Diffusion                                     #
#################################################################################


class GaussianDiffusion:
    """DDPM forward process, learned-range reverse process, hybrid loss and samplers for a given betas array."""

    def __init__(self, betas: Sequence[float] | np.ndarray, learn_sigma: bool = True, loss: str = "epsilon"):
        betas = np.asarray(betas, dtype=np.float64)
        if loss not in LOSSES:
            raise ValueError(f"loss must be one of {', '.join(LOSSES)}, got {loss!r}")
        self.loss = loss
        if betas.ndim != 1 or not ((betas > 0) & (betas <= 1)).all():
            raise ValueError("betas must be a 1-d array in (0, 1]")
        self.betas = betas
        self.num_timesteps = len(betas)
        self.learn_sigma = learn_sigma
        # model timestep t -> index of the schedule the model was trained on (identity unless respaced)
        self.timestep_map = np.arange(self.num_timesteps)

        alphas = 1.0 - betas
        self.alphas_cumprod = np.cumprod(alphas)
        self.alphas_cumprod_prev = np.append(1.0, self.alphas_cumprod[:-1])
        self.sqrt_alphas_cumprod = np.sqrt(self.alphas_cumprod)
        self.sqrt_one_minus_alphas_cumprod = np.sqrt(1.0 - self.alphas_cumprod)
        self.sqrt_recip_alphas_cumprod = np.sqrt(1.0 / self.alphas_cumprod)
        self.sqrt_recipm1_alphas_cumprod = np.sqrt(1.0 / self.alphas_cumprod - 1.0)

        # q(x_{t-1} | x_t, x_0) (Ho et al. Eq. 6-7); the variance is 0 at t = 0, so its log takes entry 1 there
        self.posterior_variance = betas * (1.0 - self.alphas_cumprod_prev) / (1.0 - self.alphas_cumprod)
        if self.num_timesteps > 1:
            self.posterior_log_variance_clipped = np.log(
                np.append(self.posterior_variance[1], self.posterior_variance[1:])
            )
        else:
            self.posterior_log_variance_clipped = np.log(betas)
        self.posterior_mean_coef1 = betas * np.sqrt(self.alphas_cumprod_prev) / (1.0 - self.alphas_cumprod)
        self.posterior_mean_coef2 = (1.0 - self.alphas_cumprod_prev) * np.sqrt(alphas) / (1.0 - self.alphas_cumprod)
        self.log_betas = np.log(betas)
        # fixed 'large' variance: beta_t with entry 0 replaced by the posterior variance at 1 (improved-diffusion)
        self.large_variance = np.append(self.posterior_variance[1], betas[1:]) if self.num_timesteps > 1 else betas
        # SNR(t) = abar_t / (1 - abar_t): the epsilon MSE is SNR(t) times the MSE of the implied x_0
        self.snr = self.alphas_cumprod / (1.0 - self.alphas_cumprod)

    # --- helpers -----------------------------------------------------------------------------------------------

    @staticmethod
    def _extract(arr: np.ndarray, t: torch.Tensor, like: torch.Tensor) -> torch.Tensor:
        """arr[t] as a tensor shaped (B, 1, ..., 1) in like's dtype and device."""
        out = torch.from_numpy(arr).to(device=t.device)[t].to(like.dtype)
        return out.reshape(out.shape + (1,) * (like.ndim - out.ndim))

    def model_timesteps(self, t: torch.Tensor) -> torch.Tensor:
        """Map timesteps of this (possibly respaced) schedule to the model's training timesteps."""
        return torch.from_numpy(self.timestep_map).to(t.device)[t]

    def _call_model(self, model_fn: ModelFn, x_t: torch.Tensor, t: torch.Tensor) -> torch.Tensor:
        out = model_fn(x_t, self.model_timesteps(t))
        channels = x_t.shape[-1] * (2 if self.learn_sigma else 1)
        if out.shape != x_t.shape[:-1] + (channels,):
            raise ValueError(f"model output has shape {tuple(out.shape)}, expected {tuple(x_t.shape[:-1]) + (channels,)}")
        return out

    def respace(self, use_timesteps: Sequence[int] | int) -> "SpacedDiffusion":
        """A diffusion over a subset of this one's timesteps (an int n: space_timesteps(T, n))."""
        if isinstance(use_timesteps, int):
            use_timesteps = space_timesteps(self.num_timesteps, use_timesteps)
        spaced = SpacedDiffusion(self.betas, use_timesteps, learn_sigma=self.learn_sigma, loss=self.loss)
        spaced.timestep_map = self.timestep_map[spaced.timestep_map]
        return spaced

    # --- forward process ---------------------------------------------------------------------------------------

    def q_mean_variance(self, x_start: torch.Tensor, t: torch.Tensor):
        """Mean, variance and log variance of q(x_t | x_0)."""
        mean = self._extract(self.sqrt_alphas_cumprod, t, x_start) * x_start
        variance = self._extract(1.0 - self.alphas_cumprod, t, x_start)
        log_variance = self._extract(np.log(1.0 - self.alphas_cumprod), t, x_start)
        return mean, variance, log_variance

    def q_sample(self, x_start: torch.Tensor, t: torch.Tensor, noise: torch.Tensor | None = None) -> torch.Tensor:
        """x_t = sqrt(abar_t) x_0 + sqrt(1 - abar_t) eps (paper Eq. 1)."""
        if noise is None:
            noise = torch.randn_like(x_start)
        return (self._extract(self.sqrt_alphas_cumprod, t, x_start) * x_start
                + self._extract(self.sqrt_one_minus_alphas_cumprod, t, x_start) * noise)

    def q_posterior_mean_variance(self, x_start: torch.Tensor, x_t: torch.Tensor, t: torch.Tensor):
        """Mean, variance and clipped log variance of q(x_{t-1} | x_t, x_0)."""
        mean = (self._extract(self.posterior_mean_coef1, t, x_t) * x_start
                + self._extract(self.posterior_mean_coef2, t, x_t) * x_t)
        variance = self._extract(self.posterior_variance, t, x_t)
        log_variance = self._extract(self.posterior_log_variance_clipped, t, x_t)
        return mean, variance, log_variance

    def predict_xstart_from_eps(self, x_t: torch.Tensor, t: torch.Tensor, eps: torch.Tensor) -> torch.Tensor:
        return (self._extract(self.sqrt_recip_alphas_cumprod, t, x_t) * x_t
                - self._extract(self.sqrt_recipm1_alphas_cumprod, t, x_t) * eps)

    def predict_eps_from_xstart(self, x_t: torch.Tensor, t: torch.Tensor, x_start: torch.Tensor) -> torch.Tensor:
        return ((self._extract(self.sqrt_recip_alphas_cumprod, t, x_t) * x_t - x_start)
                / self._extract(self.sqrt_recipm1_alphas_cumprod, t, x_t))

    # --- reverse process ---------------------------------------------------------------------------------------

    def p_mean_variance(self, model_output: torch.Tensor, x_t: torch.Tensor, t: torch.Tensor) -> dict:
        """p(x_{t-1} | x_t) from the network output: a dict of mean, variance, log_variance, pred_xstart, eps.

        Epsilon prediction; with learn_sigma, log sigma^2 = f log beta_t + (1 - f) log posterior variance,
        f = (v + 1) / 2 (Nichol & Dhariwal Eq. 15). No clipping of x_0 (docs/reference.md, Diffusion).
        """
        C = x_t.shape[-1]
        if self.learn_sigma:
            eps, v = model_output[..., :C], model_output[..., C:]
            min_log = self._extract(self.posterior_log_variance_clipped, t, x_t)
            max_log = self._extract(self.log_betas, t, x_t)
            frac = (v + 1) / 2
            log_variance = frac * max_log + (1 - frac) * min_log
            variance = torch.exp(log_variance)
        else:  # a fixed variance: beta_t (DiT's FIXED_LARGE)
            eps = model_output
            variance = self._extract(self.large_variance, t, x_t).expand_as(x_t)
            log_variance = self._extract(np.log(self.large_variance), t, x_t).expand_as(x_t)
        pred_xstart = self.predict_xstart_from_eps(x_t, t, eps)
        mean, _, _ = self.q_posterior_mean_variance(pred_xstart, x_t, t)
        return {"mean": mean, "variance": variance, "log_variance": log_variance, "pred_xstart": pred_xstart,
                "eps": eps}

    # --- loss ----------------------------------------------------------------------------------------------------

    def vb_terms_bpd(self, model_output: torch.Tensor, x_start: torch.Tensor, x_t: torch.Tensor,
                     t: torch.Tensor) -> torch.Tensor:
        """Per-sample variational-bound term in bits per dimension, (B,): KL(q(x_{t-1}|x_t,x_0) || p(x_{t-1}|x_t)),
        and at t == 0 the discretised Gaussian decoder NLL."""
        true_mean, _, true_log_variance = self.q_posterior_mean_variance(x_start, x_t, t)
        out = self.p_mean_variance(model_output, x_t, t)
        kl = mean_flat(normal_kl(true_mean, true_log_variance, out["mean"], out["log_variance"])) / math.log(2.0)
        nll = -discretized_gaussian_log_likelihood(x_start, out["mean"], 0.5 * out["log_variance"])
        nll = mean_flat(nll) / math.log(2.0)
        return torch.where(t == 0, nll, kl)

    def x0_loss_weight(self, t: torch.Tensor) -> torch.Tensor:
        """w(t) of the mean term, written as w(t) times the MSE of the implied x_0 (Hang et al. 2023, Min-SNR):
        epsilon: SNR(t) (the epsilon MSE); x0: 1; v: SNR(t) + 1 (the velocity MSE)."""
        snr = torch.from_numpy(self.snr).to(t.device)[t]
        weights = {"epsilon": snr, "x0": torch.ones_like(snr), "v": snr + 1.0}
        return weights[self.loss]

    def training_losses(self, model_fn: ModelFn, x_start: torch.Tensor, t: torch.Tensor,
                        noise: torch.Tensor | None = None, point_weight: torch.Tensor | None = None) -> dict:
        """Hybrid loss of Improved DDPM (docs/reference.md, Diffusion). Returns per-sample (B,) tensors:
        "mse" (the mean term, mean over points and channels), "vb" (zeros without learn_sigma) and "loss" = mse + vb.
        The mean term is the epsilon MSE (loss "epsilon", the paper's) or x0_loss_weight(t) times the x_0 MSE.
        `point_weight` (B, N), when given, weights each point's squared error in the mean term (normalised to a
        mean of 1 per sample, so uniform weights change nothing).
        The VB term sees the predicted mean stop-gradiented, so it trains the variance channels only."""
        if noise is None:
            noise = torch.randn_like(x_start)
        x_t = self.q_sample(x_start, t, noise)
        model_output = self._call_model(model_fn, x_t, t)
        C = x_start.shape[-1]
        eps = model_output[..., :C]
        if self.loss == "epsilon":
            mse = point_mean((noise - eps) ** 2, point_weight)
        else:
            x0 = self.predict_xstart_from_eps(x_t, t, eps)
            mse = self.x0_loss_weight(t).to(x0.dtype) * point_mean((x_start - x0) ** 2, point_weight)
        if self.learn_sigma:
            frozen = torch.cat([eps.detach(), model_output[..., C:]], dim=-1)
            vb = self.vb_terms_bpd(frozen, x_start, x_t, t)
        else:
            vb = torch.zeros_like(mse)
        return {"loss": mse + vb, "mse": mse, "vb": vb}

    def sample_timesteps(self, batch_size: int, device=None, generator: torch.Generator | None = None) -> torch.Tensor:
        """Uniformly sampled training timesteps, (B,) long."""
        return torch.randint(0, self.num_timesteps, (batch_size,), device=device, generator=generator)

    # --- samplers ------------------------------------------------------------------------------------------------

    @staticmethod
    def _noise_like(shape, generator, device, dtype=torch.float32) -> torch.Tensor:
        return torch.randn(shape, generator=generator, device=device, dtype=dtype)

    def p_sample(self, model_fn: ModelFn, x_t: torch.Tensor, t: torch.Tensor,
                 generator: torch.Generator | None = None) -> dict:
        """One ancestral step x_t -> x_{t-1}: a dict of sample and pred_xstart."""
        out = self.p_mean_variance(self._call_model(model_fn, x_t, t), x_t, t)
        noise = self._noise_like(x_t.shape, generator, x_t.device, x_t.dtype)
        nonzero = (t != 0).to(x_t.dtype).reshape(-1, *([1] * (x_t.ndim - 1)))  # no noise at t == 0
        sample = out["mean"] + nonzero * torch.exp(0.5 * out["log_variance"]) * noise
        return {"sample": sample, "pred_xstart": out["pred_xstart"]}

    def ddim_sample(self, model_fn: ModelFn, x_t: torch.Tensor, t: torch.Tensor, eta: float = 0.0,
                    generator: torch.Generator | None = None) -> dict:
        """One DDIM step (Song et al. Eq. 12) x_t -> x_{t-1}: a dict of sample and pred_xstart."""
        out = self.p_mean_variance(self._call_model(model_fn, x_t, t), x_t, t)
        eps = self.predict_eps_from_xstart(x_t, t, out["pred_xstart"])
        abar = self._extract(self.alphas_cumprod, t, x_t)
        abar_prev = self._extract(self.alphas_cumprod_prev, t, x_t)
        sigma = eta * torch.sqrt((1 - abar_prev) / (1 - abar)) * torch.sqrt(1 - abar / abar_prev)
        mean = out["pred_xstart"] * torch.sqrt(abar_prev) + torch.sqrt(1 - abar_prev - sigma**2) * eps
        sample = mean
        if eta > 0:
            noise = self._noise_like(x_t.shape, generator, x_t.device, x_t.dtype)
            nonzero = (t != 0).to(x_t.dtype).reshape(-1, *([1] * (x_t.ndim - 1)))
            sample = mean + nonzero * sigma * noise
        return {"sample": sample, "pred_xstart": out["pred_xstart"]}

    def _progressive(self, step, model_fn, shape, noise, generator, device, progress, **kw) -> Iterator[dict]:
        if noise is not None:
            x = noise
        else:
            if device is None:
                device = generator.device if generator is not None else "cpu"
            x = self._noise_like(tuple(shape), generator, device)
        yield {"t": self.num_timesteps, "sample": x, "pred_xstart": None}
        bar = None if progress is None or isinstance(progress, bool) else progress  # an open bar: one update a step
        if progress is True:
            from tqdm.auto import tqdm

            bar = tqdm(total=self.num_timesteps, desc="denoising", unit="step", leave=False)
        for i in range(self.num_timesteps - 1, -1, -1):
            t = torch.full((x.shape[0],), i, device=x.device, dtype=torch.long)
            with torch.no_grad():
                out = step(model_fn, x, t, generator=generator, **kw)
            x = out["sample"]
            if bar is not None:
                bar.update(1)
            yield {"t": i, "sample": x, "pred_xstart": out["pred_xstart"]}
        if progress is True:
            bar.close()

    def p_sample_loop_progressive(self, model_fn: ModelFn, shape, noise=None, generator=None, device=None,
                                  progress=False) -> Iterator[dict]:
        """Yields {"t", "sample", "pred_xstart"}: first x_T (t = T), then x_{t} after each step down to t = 0.
        progress: True for a bar of its own, or an open tqdm bar to advance once per step."""
        yield from self._progressive(self.p_sample, model_fn, shape, noise, generator, device, progress)

    def ddim_sample_loop_progressive(self, model_fn: ModelFn, shape, noise=None, generator=None, device=None,
                                     progress: bool = False, eta: float = 0.0) -> Iterator[dict]:
        """As p_sample_loop_progressive, with DDIM steps."""
        yield from self._progressive(self.ddim_sample, model_fn, shape, noise, generator, device, progress, eta=eta)

    @staticmethod
    def _collect(steps: Iterator[dict], return_trajectory: bool):
        trajectory = [s["sample"] for s in steps]
        if return_trajectory:
            return trajectory[-1], torch.stack(trajectory)
        return trajectory[-1]

    def p_sample_loop(self, model_fn: ModelFn, shape, noise=None, generator=None, device=None,
                      progress: bool = False, return_trajectory: bool = False):
        """Ancestral sampling from x_T ~ N(0, I) (or noise). Returns x_0, or (x_0, trajectory) with the trajectory
        (S + 1, *shape) holding x_T, ..., x_0 for S = num_timesteps steps."""
        steps = self.p_sample_loop_progressive(model_fn, shape, noise, generator, device, progress)
        return self._collect(steps, return_trajectory)

    def ddim_sample_loop(self, model_fn: ModelFn, shape, noise=None, generator=None, device=None,
                         progress: bool = False, return_trajectory: bool = False, eta: float = 0.0):
        """DDIM sampling (eta = 0: deterministic). Returns as p_sample_loop."""
        steps = self.ddim_sample_loop_progressive(model_fn, shape, noise, generator, device, progress, eta)
        return self._collect(steps, return_trajectory)


class SpacedDiffusion(GaussianDiffusion):
    """A diffusion on a subset of a base schedule's timesteps, e.g. 10 of the 100 a model was trained with.

    The kept steps keep their alphas_cumprod; betas are recomputed as 1 - abar_i / abar_prev(i), and the model is
    called with the original timestep indices (improved-diffusion's respacing)."""

    def __init__(self, betas: Sequence[float] | np.ndarray, use_timesteps: Sequence[int], **kwargs):
        betas = np.asarray(betas, dtype=np.float64)
        keep = sorted({int(i) for i in use_timesteps})
        if not keep or keep[0] < 0 or keep[-1] >= len(betas):
            raise ValueError(f"use_timesteps must be a non-empty subset of range({len(betas)})")
        base_alphas_cumprod = np.cumprod(1.0 - betas)[keep]
        prev = np.append(1.0, base_alphas_cumprod[:-1])
        super().__init__(1.0 - base_alphas_cumprod / prev, **kwargs)
        self.timestep_map = np.asarray(keep, dtype=np.int64)
        self.original_num_timesteps = len(betas)
