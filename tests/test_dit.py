"""Shapes, symmetries and initialisation of the point-cloud DiTs."""

import pytest
import torch

from tax3d import config as cfg
from tax3d.model.dit import DiTPointCloudCross, DiTPointCloudScene
from tax3d.model.tax3d import build_network


def paper_network(**kw) -> DiTPointCloudCross:
    """The network of the `paper` preset (its size lives in tax3d.config alone)."""
    m = cfg.paper().model
    return DiTPointCloudCross(**{"hidden_size": m.hidden_size, "depth": m.depth, "num_heads": m.num_heads, **kw})

B, N, M = 2, 10, 7
TINY = dict(hidden_size=32, depth=2, num_heads=4)


def randomise_zeroed_layers(model):
    """Give the zero-initialised adaLN and output layers random weights, so the tests see a non-trivial map."""
    torch.manual_seed(1)
    for name, p in model.named_parameters():
        if "adaLN_modulation" in name or "final_layer.linear" in name:
            torch.nn.init.normal_(p, std=0.2)
    return model


def inputs(seed=0):
    g = torch.Generator().manual_seed(seed)
    return (torch.randn(B, N, 3, generator=g), torch.randint(0, 100, (B,), generator=g),
            torch.randn(B, N, 3, generator=g), torch.randn(B, M, 3, generator=g))


@pytest.mark.parametrize("learn_sigma", [True, False])
@pytest.mark.parametrize("action_context", [True, False])
@pytest.mark.parametrize("time_conditioning", [True, False])
def test_cross_shapes(learn_sigma, action_context, time_conditioning):
    torch.manual_seed(0)
    model = DiTPointCloudCross(learn_sigma=learn_sigma, action_context=action_context,
                               time_conditioning=time_conditioning, **TINY)
    x, t, action, anchor = inputs()
    out = model(x, t if time_conditioning else None, action if action_context else None, anchor)
    assert out.shape == (B, N, 6 if learn_sigma else 3)
    assert model.out_channels == out.shape[-1]
    if not time_conditioning:
        assert model.t_embedder is None


def test_cross_takes_float_and_scalar_timesteps():
    model = randomise_zeroed_layers(DiTPointCloudCross(**TINY))
    x, t, action, anchor = inputs()
    torch.testing.assert_close(model(x, t.float(), action, anchor), model(x, t, action, anchor))
    assert model(x, torch.tensor(5), action, anchor).shape == (B, N, 6)


def test_cross_errors_on_missing_inputs():
    x, t, action, anchor = inputs()
    with pytest.raises(ValueError):
        DiTPointCloudCross(**TINY)(x, t, None, anchor)
    with pytest.raises(ValueError):
        DiTPointCloudCross(**TINY)(x, None, action, anchor)


def test_encoder_widths():
    model = paper_network()
    assert model.x_embedder.out_features == 64 and model.action_embedder.out_features == 64
    assert model.anchor_embedder.out_features == 128
    nac = paper_network(action_context=False)
    assert nac.x_embedder.out_features == 128 and nac.action_embedder is None


@pytest.mark.parametrize("learn_sigma", [True, False])
def test_scene_shapes(learn_sigma):
    torch.manual_seed(0)
    model = DiTPointCloudScene(learn_sigma=learn_sigma, **TINY)
    x, scene = torch.randn(B, N + M, 3), torch.randn(B, N + M, 3)
    out = model(x, torch.tensor([3, 60]), scene)
    assert out.shape == (B, N + M, 6 if learn_sigma else 3)
    assert DiTPointCloudScene(time_conditioning=False, **TINY)(x, None, scene).shape == (B, N + M, 6)


@pytest.mark.parametrize("action_context", [True, False])
def test_cross_permutation_equivariance(action_context):
    torch.manual_seed(0)
    model = randomise_zeroed_layers(DiTPointCloudCross(action_context=action_context, **TINY)).eval()
    x, t, action, anchor = inputs()
    action = action if action_context else None
    out = model(x, t, action, anchor)
    assert out.abs().max() > 1e-3  # a non-trivial map
    perm = torch.randperm(N)
    out_perm = model(x[:, perm], t, None if action is None else action[:, perm], anchor)
    torch.testing.assert_close(out_perm, out[:, perm], atol=1e-5, rtol=1e-5)
    # invariant to the order of the anchor points
    out_anchor = model(x, t, action, anchor[:, torch.randperm(M)])
    torch.testing.assert_close(out_anchor, out, atol=1e-5, rtol=1e-5)


def test_scene_permutation_equivariance():
    torch.manual_seed(0)
    model = randomise_zeroed_layers(DiTPointCloudScene(**TINY)).eval()
    x, scene = torch.randn(B, N + M, 3), torch.randn(B, N + M, 3)
    t = torch.tensor([3, 60])
    perm = torch.randperm(N + M)
    torch.testing.assert_close(model(x[:, perm], t, scene[:, perm]), model(x, t, scene)[:, perm],
                               atol=1e-5, rtol=1e-5)


def test_fresh_network_outputs_exactly_zero():
    torch.manual_seed(0)
    x, t, action, anchor = inputs()
    assert (DiTPointCloudCross(**TINY)(x, t, action, anchor) == 0).all()
    assert (DiTPointCloudCross(time_conditioning=False, **TINY)(x, None, action, anchor) == 0).all()
    scene = torch.randn(B, N + M, 3)
    assert (DiTPointCloudScene(**TINY)(scene, t, scene) == 0).all()


def test_initialisation():
    torch.manual_seed(0)
    model = paper_network()
    for block in model.blocks:
        assert (block.adaLN_modulation[-1].weight == 0).all() and (block.adaLN_modulation[-1].bias == 0).all()
        assert (block.self_attn.qkv.bias == 0).all() and block.self_attn.qkv.weight.abs().max() > 0
    assert (model.final_layer.linear.weight == 0).all()
    std = model.t_embedder.mlp[0].weight.std().item()
    assert 0.015 < std < 0.025


def test_gradients_reach_every_parameter_after_a_few_steps():
    # adaLN-Zero: at init only the output Linear gets gradients; each step opens the next layers up
    torch.manual_seed(0)
    model = DiTPointCloudCross(**TINY)
    x, t, action, anchor = inputs()
    opt = torch.optim.SGD(model.parameters(), lr=0.1)
    for step in range(3):
        opt.zero_grad()
        (model(x, t, action, anchor) - 1).square().mean().backward()
        opt.step()
        with_grad = {n for n, p in model.named_parameters() if p.grad is not None and p.grad.abs().sum() > 0}
        if step == 0:
            assert with_grad == {"final_layer.linear.weight", "final_layer.linear.bias"}
    assert with_grad == {n for n, _ in model.named_parameters()}


def test_preset_parameter_counts():
    paper = sum(p.numel() for p in build_network(cfg.paper()).parameters())
    cpu = sum(p.numel() for p in build_network(cfg.cpu()).parameters())
    assert 1.5e6 < paper < 3e6
    assert cpu < paper / 3
