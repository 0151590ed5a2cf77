"""Diffusion maths against independent oracles: diffusers' DDPMScheduler, torch.distributions, closed forms."""

import math

import numpy as np
import pytest
import torch

from tax3d.model.diffusion import (
    GaussianDiffusion,
    SpacedDiffusion,
    discretized_gaussian_log_likelihood,
    linear_betas,
    normal_kl,
    space_timesteps,
)

T = 100


@pytest.fixture
def diffusion():
    return GaussianDiffusion(linear_betas(T))


def ddpm_oracle(betas, **kw):
    diffusers = pytest.importorskip("diffusers")
    return diffusers.DDPMScheduler(
        num_train_timesteps=len(betas), trained_betas=betas.tolist(), variance_type="learned_range",
        clip_sample=False, **kw,
    )


def oracle_eps_model(diffusion, x0, learn_sigma=True):
    """A model that returns the true epsilon for a known x_0 (called with original timesteps)."""
    base = GaussianDiffusion(linear_betas(T))

    def model_fn(x_t, t):
        eps = base.predict_eps_from_xstart(x_t, t, x0.expand_as(x_t))
        return torch.cat([eps, torch.zeros_like(eps)], -1) if learn_sigma else eps

    return model_fn


def test_linear_betas():
    betas = linear_betas(100)
    assert betas.dtype == np.float64 and betas.shape == (100,)
    assert betas[0] == pytest.approx(0.001) and betas[-1] == pytest.approx(0.2)
    assert linear_betas(1000)[-1] == pytest.approx(0.02)


def test_alphas_cumprod_match_diffusers(diffusion):
    sched = ddpm_oracle(diffusion.betas)
    np.testing.assert_allclose(diffusion.alphas_cumprod, sched.alphas_cumprod.double().numpy(), rtol=1e-5)


def test_posterior_and_learned_range_match_diffusers(diffusion):
    torch.manual_seed(0)
    sched = ddpm_oracle(diffusion.betas)
    B, N, C = 2, 7, 3
    for step in [1, 2, 10, 50, 99]:
        t = torch.full((B,), step)
        x_t = torch.randn(B, N, C, dtype=torch.float64)
        eps = torch.randn(B, N, C, dtype=torch.float64)
        v = torch.rand(B, N, C, dtype=torch.float64) * 2 - 1
        out = diffusion.p_mean_variance(torch.cat([eps, v], -1), x_t, t)

        # learned-range log variance
        ref_logvar = sched._get_variance(step, predicted_variance=v.float()).double()
        torch.testing.assert_close(out["log_variance"], ref_logvar, rtol=1e-5, atol=1e-5)
        # v = -1: the posterior variance itself
        _, post_var, post_logvar = diffusion.q_posterior_mean_variance(x_t, x_t, t)
        ref_var = sched._get_variance(step, variance_type="fixed_small").double()
        assert post_var[0].item() == pytest.approx(ref_var.item(), rel=1e-4)  # diffusers works in float32
        assert post_logvar[0].item() == pytest.approx(math.log(ref_var.item()), rel=1e-4)

        # posterior mean and x_0 prediction: one diffusers step (channel-first) with the same noise
        gen = torch.Generator().manual_seed(step)
        ref = sched.step(torch.cat([eps, v], -1).transpose(1, 2).float(), step, x_t.transpose(1, 2).float(),
                         generator=gen)
        noise = torch.randn(B, C, N, generator=torch.Generator().manual_seed(step)).transpose(1, 2).double()
        mine = out["mean"] + torch.exp(0.5 * out["log_variance"]) * noise
        torch.testing.assert_close(out["pred_xstart"].float(), ref.pred_original_sample.transpose(1, 2),
                                   rtol=1e-4, atol=1e-4)
        torch.testing.assert_close(mine.float(), ref.prev_sample.transpose(1, 2), rtol=1e-4, atol=1e-4)


def test_log_variance_clipped_at_t0(diffusion):
    assert diffusion.posterior_variance[0] == 0.0
    assert diffusion.posterior_log_variance_clipped[0] == diffusion.posterior_log_variance_clipped[1]
    assert np.isfinite(diffusion.posterior_log_variance_clipped).all()


def test_q_sample_matches_diffusers_add_noise(diffusion):
    sched = ddpm_oracle(diffusion.betas)
    torch.manual_seed(1)
    x0, noise = torch.randn(4, 5, 3), torch.randn(4, 5, 3)
    t = torch.tensor([0, 3, 40, 99])
    torch.testing.assert_close(diffusion.q_sample(x0, t, noise), sched.add_noise(x0, noise, t), rtol=1e-5, atol=1e-5)


def test_normal_kl_matches_torch_distributions():
    torch.manual_seed(2)
    m1, m2, lv1, lv2 = (torch.randn(50, dtype=torch.float64) for _ in range(4))
    ref = torch.distributions.kl_divergence(
        torch.distributions.Normal(m1, torch.exp(0.5 * lv1)), torch.distributions.Normal(m2, torch.exp(0.5 * lv2))
    )
    torch.testing.assert_close(normal_kl(m1, lv1, m2, lv2), ref)


def test_discretized_likelihood_sums_to_one_over_bins():
    # the 256 bins of [-1, 1] (edges take the tails) partition the real line
    x = torch.linspace(-1, 1, 256, dtype=torch.float64)
    for mean, log_scale in [(0.0, -1.0), (0.3, -3.0), (-0.9, 0.5)]:
        ll = discretized_gaussian_log_likelihood(x, torch.full_like(x, mean), torch.full_like(x, log_scale))
        assert torch.exp(ll).sum().item() == pytest.approx(1.0, abs=1e-6)


def test_space_timesteps():
    assert space_timesteps(100, 10) == [0, 11, 22, 33, 44, 55, 66, 77, 88, 99]
    assert space_timesteps(100, 100) == list(range(100))
    assert space_timesteps(100, 1) == [99]
    with pytest.raises(ValueError):
        space_timesteps(100, 101)


def test_respaced_schedule_keeps_alphas_cumprod(diffusion):
    keep = space_timesteps(T, 10)
    spaced = diffusion.respace(10)
    assert isinstance(spaced, SpacedDiffusion) and spaced.num_timesteps == 10
    np.testing.assert_allclose(spaced.alphas_cumprod, diffusion.alphas_cumprod[keep], rtol=1e-12)
    np.testing.assert_array_equal(spaced.timestep_map, keep)
    # respacing a respaced diffusion maps back to the original indices
    twice = spaced.respace([0, 5, 9])
    np.testing.assert_array_equal(twice.timestep_map, [keep[0], keep[5], keep[9]])
    np.testing.assert_allclose(twice.alphas_cumprod, diffusion.alphas_cumprod[twice.timestep_map], rtol=1e-12)


def test_respaced_step_matches_diffusers_custom_timesteps(diffusion):
    spaced = diffusion.respace(10)
    sched = ddpm_oracle(diffusion.betas)
    sched.set_timesteps(timesteps=spaced.timestep_map[::-1].tolist())
    torch.manual_seed(3)
    B, N, C = 2, 6, 3
    for k in [1, 4, 9]:
        orig = int(spaced.timestep_map[k])
        x_t = torch.randn(B, N, C)
        out_ch = torch.cat([torch.randn(B, N, C), torch.rand(B, N, C) * 2 - 1], -1)
        out = spaced.p_mean_variance(out_ch, x_t, torch.full((B,), k))
        ref = sched.step(out_ch.transpose(1, 2), orig, x_t.transpose(1, 2), generator=torch.Generator().manual_seed(k))
        noise = torch.randn(B, C, N, generator=torch.Generator().manual_seed(k)).transpose(1, 2)
        mine = out["mean"] + torch.exp(0.5 * out["log_variance"]) * noise
        torch.testing.assert_close(mine, ref.prev_sample.transpose(1, 2), rtol=1e-4, atol=1e-4)


def test_ddim_step_matches_diffusers(diffusion):
    diffusers = pytest.importorskip("diffusers")
    sched = diffusers.DDIMScheduler(num_train_timesteps=T, trained_betas=diffusion.betas.tolist(),
                                    clip_sample=False, set_alpha_to_one=True)
    sched.set_timesteps(T)
    torch.manual_seed(7)
    for step in [99, 50, 1, 0]:
        x_t, eps, v = torch.randn(2, 5, 3), torch.randn(2, 5, 3), torch.rand(2, 5, 3) * 2 - 1
        mine = diffusion.ddim_sample(lambda x, t: torch.cat([eps, v], -1), x_t, torch.full((2,), step))["sample"]
        ref = sched.step(eps.transpose(1, 2), step, x_t.transpose(1, 2), eta=0.0).prev_sample.transpose(1, 2)
        torch.testing.assert_close(mine, ref, rtol=1e-5, atol=1e-5)


@pytest.mark.parametrize("learn_sigma", [True, False])
def test_samplers_recover_x0_with_oracle_model(learn_sigma):
    torch.manual_seed(4)
    x0 = torch.randn(1, 16, 3) * 3 + 5  # DEDO-like magnitudes
    base = GaussianDiffusion(linear_betas(T), learn_sigma=learn_sigma)
    model_fn = oracle_eps_model(base, x0, learn_sigma)
    for d in [base, base.respace(10)]:
        gen = torch.Generator().manual_seed(0)
        sample, traj = d.p_sample_loop(model_fn, (2, 16, 3), generator=gen, return_trajectory=True)
        assert traj.shape == (d.num_timesteps + 1, 2, 16, 3)
        torch.testing.assert_close(traj[-1], sample)
        torch.testing.assert_close(sample, x0.expand_as(sample), rtol=1e-4, atol=1e-4)
        sample = d.ddim_sample_loop(model_fn, (2, 16, 3), generator=torch.Generator().manual_seed(0))
        torch.testing.assert_close(sample, x0.expand_as(sample), rtol=1e-4, atol=1e-4)


def test_progressive_yields_every_step(diffusion):
    x0 = torch.zeros(1, 4, 3)
    steps = list(diffusion.respace(5).ddim_sample_loop_progressive(oracle_eps_model(diffusion, x0), (1, 4, 3)))
    assert [s["t"] for s in steps] == [5, 4, 3, 2, 1, 0]


def test_training_losses_and_stop_gradient(diffusion):
    torch.manual_seed(5)
    B, N, C = 4, 8, 3
    x0 = torch.randn(B, N, C)
    t = torch.tensor([0, 1, 30, 99])
    noise = torch.randn(B, N, C)
    out = torch.randn(B, N, 2 * C, requires_grad=True)
    losses = diffusion.training_losses(lambda x_t, tt: out, x0, t, noise)
    assert set(losses) == {"loss", "mse", "vb"}
    for v in losses.values():
        assert v.shape == (B,) and torch.isfinite(v).all()
    torch.testing.assert_close(losses["mse"], ((noise - out[..., :C]) ** 2).mean(dim=(1, 2)))
    torch.testing.assert_close(losses["loss"], losses["mse"] + losses["vb"])

    (g_vb,) = torch.autograd.grad(losses["vb"].sum(), out, retain_graph=True)
    assert (g_vb[..., :C] == 0).all()  # the mean is stop-gradiented in the VB term
    assert (g_vb[..., C:].abs() > 0).any()
    (g_mse,) = torch.autograd.grad(losses["mse"].sum(), out)
    assert (g_mse[..., C:] == 0).all()


def test_vb_vanishes_for_true_eps_and_posterior_variance(diffusion):
    torch.manual_seed(6)
    x0 = torch.randn(3, 8, 3, dtype=torch.float64)
    t = torch.tensor([1, 20, 99])
    noise = torch.randn_like(x0)
    # v = -1 selects the (clipped) posterior variance, exact for t >= 1
    losses = diffusion.training_losses(lambda x_t, tt: torch.cat([noise, -torch.ones_like(noise)], -1), x0, t, noise)
    torch.testing.assert_close(losses["vb"], torch.zeros(3, dtype=torch.float64), atol=1e-9, rtol=0)
    torch.testing.assert_close(losses["mse"], torch.zeros(3, dtype=torch.float64))


def test_training_losses_without_learned_sigma():
    d = GaussianDiffusion(linear_betas(T), learn_sigma=False)
    x0 = torch.randn(2, 5, 3)
    losses = d.training_losses(lambda x_t, t: torch.zeros_like(x_t), x0, torch.tensor([0, 50]))
    assert (losses["vb"] == 0).all() and torch.isfinite(losses["loss"]).all()
    with pytest.raises(ValueError):
        d.training_losses(lambda x_t, t: torch.zeros(2, 5, 6), x0, torch.tensor([0, 50]))


def test_model_sees_original_timesteps(diffusion):
    spaced = diffusion.respace(10)
    seen = []

    def model_fn(x_t, t):
        seen.append(t.tolist())
        return torch.zeros(*x_t.shape[:-1], 6)

    spaced.p_sample_loop(model_fn, (1, 2, 3), generator=torch.Generator().manual_seed(0))
    assert [s[0] for s in seen] == space_timesteps(T, 10)[::-1]


@pytest.mark.parametrize("loss", ["x0", "v"])
def test_x0_loss_weights(loss):
    """The mean term is w(t) times the x_0 MSE: w = 1 for x0 (no dependence on t), SNR + 1 for v."""
    d = GaussianDiffusion(linear_betas(T), loss=loss)
    torch.manual_seed(7)
    x0 = torch.randn(3, 8, 3, dtype=torch.float64)
    t = torch.tensor([0, 10, 99])
    noise = torch.randn_like(x0)
    error = 0.3 * torch.randn_like(x0)
    x_t = d.q_sample(x0, t, noise)
    eps = d.predict_eps_from_xstart(x_t, t, x0 + error)  # a network whose x_0 is off by `error`
    out = torch.cat([eps, torch.zeros_like(eps)], -1)
    mse = d.training_losses(lambda x, tt: out, x0, t, noise)["mse"]
    snr = torch.from_numpy(d.alphas_cumprod / (1 - d.alphas_cumprod))[t]
    weight = {"x0": torch.ones(3, dtype=torch.float64), "v": snr + 1}[loss]
    torch.testing.assert_close(mse, weight * (error**2).mean(dim=(1, 2)))
    if loss == "x0":
        assert torch.allclose(d.x0_loss_weight(torch.arange(T)), torch.ones(T, dtype=torch.float64))


def test_epsilon_loss_is_snr_weighted_x0_error(diffusion):
    """The paper's epsilon MSE, written in x_0 terms, weights the error by SNR(t): heavily at small t."""
    x0 = torch.randn(2, 8, 3, dtype=torch.float64)
    t = torch.tensor([0, 99])
    noise = torch.randn_like(x0)
    error = 0.3 * torch.randn_like(x0)
    x_t = diffusion.q_sample(x0, t, noise)
    eps = diffusion.predict_eps_from_xstart(x_t, t, x0 + error)
    mse = diffusion.training_losses(lambda x, tt: torch.cat([eps, torch.zeros_like(eps)], -1), x0, t, noise)["mse"]
    snr = torch.from_numpy(diffusion.snr)[t]
    torch.testing.assert_close(mse, snr * (error**2).mean(dim=(1, 2)))
    assert snr[0] > 1000 * snr[1]
    with pytest.raises(ValueError):
        GaussianDiffusion(linear_betas(T), loss="l1")


@pytest.mark.parametrize("loss", ["epsilon", "v"])
def test_point_weights(diffusion, loss):
    """Per-point weights: uniform ones change nothing; otherwise each point's error counts by its weight."""
    d = GaussianDiffusion(linear_betas(T), loss=loss)
    torch.manual_seed(3)
    x0 = torch.randn(2, 6, 3, dtype=torch.float64)
    t, noise = torch.tensor([5, 60]), torch.randn_like(x0)
    out = torch.randn(2, 6, 6, dtype=torch.float64)
    plain = d.training_losses(lambda x, tt: out, x0, t, noise)["mse"]
    torch.testing.assert_close(d.training_losses(lambda x, tt: out, x0, t, noise, torch.full((2, 6), 3.0))["mse"],
                               plain)
    weight = torch.ones(2, 6, dtype=torch.float64)
    weight[:, 0] = 0.0
    out_rest = out[:, 1:]
    masked = d.training_losses(lambda x, tt: out_rest, x0[:, 1:], t, noise[:, 1:])["mse"]
    torch.testing.assert_close(d.training_losses(lambda x, tt: out, x0, t, noise, weight)["mse"], masked)
