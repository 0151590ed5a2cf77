"""Diffusion Transformer over point clouds: TAX3D's cross-attention DiT and the scene (self-only) variant.

Paper Sec. 3.2 and App. B.1; the facts the paper leaves out are in docs/reference.md, "Model".
No positional encoding anywhere: every network here is permutation-equivariant over its query points.
"""

from __future__ import annotations

import math

import torch
import torch.nn as nn
import torch.nn.functional as F


def modulate(x: torch.Tensor, shift: torch.Tensor, scale: torch.Tensor) -> torch.Tensor:
    # adaLN: per-sample shift and scale broadcast over the points
    return x * (1 + scale.unsqueeze(1)) + shift.unsqueeze(1)


def _layer_norm(hidden_size: int) -> nn.LayerNorm:
    return nn.LayerNorm(hidden_size, elementwise_affine=False, eps=1e-6)


#################################################################################
#                             Embedding layers                                  #
#################################################################################


class TimestepEmbedder(nn.Module):
    """Embeds scalar diffusion timesteps: a 256-d sinusoid, then Linear-SiLU-Linear to the hidden size."""

    def __init__(self, hidden_size: int, frequency_size: int = 256, max_period: float = 10000.0):
        super().__init__()
        self.frequency_size = frequency_size
        self.max_period = max_period
        self.mlp = nn.Sequential(
            nn.Linear(frequency_size, hidden_size),
            nn.SiLU(),
            nn.Linear(hidden_size, hidden_size),
        )

    def sinusoid(self, t: torch.Tensor) -> torch.Tensor:
        # cos/sin at frequencies max_period^(-k/half), k = 0..half-1 (the DiT / ADM embedding)
        half = self.frequency_size // 2
        k = torch.arange(half, device=t.device, dtype=torch.float32)
        freqs = torch.exp(-math.log(self.max_period) * k / half)  # (half,)
        angles = t.float()[:, None] * freqs[None, :]  # (B, half)
        emb = torch.cat([torch.cos(angles), torch.sin(angles)], dim=-1)  # (B, 2 half)
        if self.frequency_size % 2:
            emb = F.pad(emb, (0, 1))
        return emb

    def forward(self, t: torch.Tensor) -> torch.Tensor:
        return self.mlp(self.sinusoid(t))  # (B, D)


#################################################################################
#                          Attention and MLP layers                             #
#################################################################################


class SelfAttention(nn.Module):
    """Multi-head self-attention over a set of tokens (qkv with bias)."""

    def __init__(self, hidden_size: int, num_heads: int):
        super().__init__()
        assert hidden_size % num_heads == 0, "hidden_size must be divisible by num_heads"
        self.num_heads = num_heads
        self.qkv = nn.Linear(hidden_size, 3 * hidden_size, bias=True)
        self.proj = nn.Linear(hidden_size, hidden_size)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        B, N, D = x.shape
        qkv = self.qkv(x).reshape(B, N, 3, self.num_heads, D // self.num_heads)  # (B, N, 3, H, D/H)
        q, k, v = qkv.permute(2, 0, 3, 1, 4)  # 3 x (B, H, N, D/H)
        x = F.scaled_dot_product_attention(q, k, v)  # (B, H, N, D/H)
        x = x.transpose(1, 2).reshape(B, N, D)  # (B, N, D)
        return self.proj(x)  # (B, N, D)


class CrossAttention(nn.Module):
    """Multi-head cross-attention: queries from action tokens, keys and values from anchor tokens."""

    def __init__(self, hidden_size: int, num_heads: int):
        super().__init__()
        assert hidden_size % num_heads == 0, "hidden_size must be divisible by num_heads"
        self.num_heads = num_heads
        self.q = nn.Linear(hidden_size, hidden_size, bias=True)
        self.kv = nn.Linear(hidden_size, 2 * hidden_size, bias=True)
        self.proj = nn.Linear(hidden_size, hidden_size)

    def forward(self, x: torch.Tensor, y: torch.Tensor) -> torch.Tensor:
        B, N, D = x.shape
        M = y.shape[1]
        H = self.num_heads
        q = self.q(x).reshape(B, N, H, D // H).transpose(1, 2)  # (B, H, N, D/H)
        kv = self.kv(y).reshape(B, M, 2, H, D // H)  # (B, M, 2, H, D/H)
        k, v = kv.permute(2, 0, 3, 1, 4)  # 2 x (B, H, M, D/H)
        x = F.scaled_dot_product_attention(q, k, v)  # (B, H, N, D/H)
        x = x.transpose(1, 2).reshape(B, N, D)  # (B, N, D)
        return self.proj(x)  # (B, N, D)


class Mlp(nn.Module):
    """Point-wise two-layer MLP with tanh-approximated GELU."""

    def __init__(self, hidden_size: int, mlp_ratio: float = 4.0):
        super().__init__()
        inner = int(hidden_size * mlp_ratio)
        self.fc1 = nn.Linear(hidden_size, inner)
        self.act = nn.GELU(approximate="tanh")
        self.fc2 = nn.Linear(inner, hidden_size)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.fc2(self.act(self.fc1(x)))


#################################################################################
#                                DiT blocks                                     #
#################################################################################


class DiTCrossBlock(nn.Module):
    """adaLN-Zero block: self-attention over action tokens, cross-attention to anchor tokens, MLP."""

    def __init__(self, hidden_size: int, num_heads: int, mlp_ratio: float = 4.0):
        super().__init__()
        self.norm1 = _layer_norm(hidden_size)
        self.self_attn = SelfAttention(hidden_size, num_heads)
        self.norm2 = _layer_norm(hidden_size)
        self.cross_attn = CrossAttention(hidden_size, num_heads)
        self.norm3 = _layer_norm(hidden_size)
        self.mlp = Mlp(hidden_size, mlp_ratio)
        # shift/scale/gate for self-attention, cross-attention and the MLP (docs/reference.md, Model)
        self.adaLN_modulation = nn.Sequential(nn.SiLU(), nn.Linear(hidden_size, 9 * hidden_size))

    def forward(self, x: torch.Tensor, anchor: torch.Tensor, c: torch.Tensor) -> torch.Tensor:
        (shift_sa, scale_sa, gate_sa,
         shift_ca, scale_ca, gate_ca,
         shift_mlp, scale_mlp, gate_mlp) = self.adaLN_modulation(c).chunk(9, dim=-1)  # 9 x (B, D)
        x = x + gate_sa.unsqueeze(1) * self.self_attn(modulate(self.norm1(x), shift_sa, scale_sa))  # (B, N, D)
        x = x + gate_ca.unsqueeze(1) * self.cross_attn(
            modulate(self.norm2(x), shift_ca, scale_ca), anchor
        )  # (B, N, D)
        x = x + gate_mlp.unsqueeze(1) * self.mlp(modulate(self.norm3(x), shift_mlp, scale_mlp))  # (B, N, D)
        return x


class DiTSelfBlock(nn.Module):
    """Classic adaLN-Zero DiT block (self-attention and MLP), used by the scene variants SD/SP."""

    def __init__(self, hidden_size: int, num_heads: int, mlp_ratio: float = 4.0):
        super().__init__()
        self.norm1 = _layer_norm(hidden_size)
        self.self_attn = SelfAttention(hidden_size, num_heads)
        self.norm2 = _layer_norm(hidden_size)
        self.mlp = Mlp(hidden_size, mlp_ratio)
        self.adaLN_modulation = nn.Sequential(nn.SiLU(), nn.Linear(hidden_size, 6 * hidden_size))

    def forward(self, x: torch.Tensor, c: torch.Tensor) -> torch.Tensor:
        shift_sa, scale_sa, gate_sa, shift_mlp, scale_mlp, gate_mlp = self.adaLN_modulation(c).chunk(6, dim=-1)
        x = x + gate_sa.unsqueeze(1) * self.self_attn(modulate(self.norm1(x), shift_sa, scale_sa))  # (B, N, D)
        x = x + gate_mlp.unsqueeze(1) * self.mlp(modulate(self.norm2(x), shift_mlp, scale_mlp))  # (B, N, D)
        return x


class FinalLayer(nn.Module):
    """adaLN shift/scale, then a point-wise Linear to the output channels."""

    def __init__(self, hidden_size: int, out_channels: int):
        super().__init__()
        self.norm_final = _layer_norm(hidden_size)
        self.linear = nn.Linear(hidden_size, out_channels)
        self.adaLN_modulation = nn.Sequential(nn.SiLU(), nn.Linear(hidden_size, 2 * hidden_size))

    def forward(self, x: torch.Tensor, c: torch.Tensor) -> torch.Tensor:
        shift, scale = self.adaLN_modulation(c).chunk(2, dim=-1)  # 2 x (B, D)
        x = modulate(self.norm_final(x), shift, scale)  # (B, N, D)
        return self.linear(x)  # (B, N, C_out)


#################################################################################
#                                Networks                                       #
#################################################################################


class _PointDiT(nn.Module):
    """Shared conditioning and initialisation of the point-cloud DiTs."""

    hidden_size: int
    time_conditioning: bool
    blocks: nn.ModuleList
    final_layer: FinalLayer

    def _setup(self, in_channels: int, hidden_size: int, num_heads: int, learn_sigma: bool) -> None:
        """The sizes both networks share."""
        self.in_channels, self.hidden_size, self.num_heads = in_channels, hidden_size, num_heads
        self.learn_sigma = learn_sigma
        # the output (3) + the variance interpolation v (3) when the variance is learned
        self.out_channels = 2 * in_channels if learn_sigma else in_channels

    def _make_conditioning(self, time_conditioning: bool) -> None:
        """Made after the point encoders, so that a seed gives the weights it always gave."""
        self.time_conditioning = time_conditioning
        # Without time conditioning (regression variants RD/RP) the conditioning vector is zeros: SiLU(0) = 0,
        # so every adaLN Linear reduces to its bias, a learned constant shift/scale/gate per block.
        self.t_embedder = TimestepEmbedder(self.hidden_size) if time_conditioning else None

    def conditioning(self, t: torch.Tensor | None, batch_size: int, like: torch.Tensor) -> torch.Tensor:
        if self.t_embedder is None:
            return like.new_zeros(batch_size, self.hidden_size)  # (B, D)
        if t is None:
            raise ValueError("this network is time-conditioned: pass the diffusion timesteps t, shape (B,)")
        t = torch.as_tensor(t, device=like.device)
        if t.ndim == 0:
            t = t.expand(batch_size)
        return self.t_embedder(t)  # (B, D)

    def initialize_weights(self) -> None:
        # Every Linear (point encoders, attention, MLP): Xavier-uniform weights, zero biases.
        def _basic_init(module: nn.Module) -> None:
            if isinstance(module, nn.Linear):
                nn.init.xavier_uniform_(module.weight)
                if module.bias is not None:
                    nn.init.zeros_(module.bias)

        self.apply(_basic_init)

        # Timestep MLP: N(0, 0.02) weights, as DiT.
        if self.t_embedder is not None:
            nn.init.normal_(self.t_embedder.mlp[0].weight, std=0.02)
            nn.init.normal_(self.t_embedder.mlp[2].weight, std=0.02)

        # adaLN-Zero: zero every modulation layer so each block starts as the identity (gates = 0), and zero the
        # output layer so the fresh network predicts exactly 0 (epsilon = 0, variance interpolation v = 0).
        for block in self.blocks:
            nn.init.zeros_(block.adaLN_modulation[-1].weight)
            nn.init.zeros_(block.adaLN_modulation[-1].bias)
        nn.init.zeros_(self.final_layer.adaLN_modulation[-1].weight)
        nn.init.zeros_(self.final_layer.adaLN_modulation[-1].bias)
        nn.init.zeros_(self.final_layer.linear.weight)
        nn.init.zeros_(self.final_layer.linear.bias)


class DiTPointCloudCross(_PointDiT):
    """TAX3D's network: noised cross-displacements (or goal points) + action context, cross-attending to the anchor."""

    def __init__(
        self,
        in_channels: int = 3,
        hidden_size: int = 128,
        depth: int = 5,
        num_heads: int = 4,
        mlp_ratio: float = 4.0,
        learn_sigma: bool = True,
        action_context: bool = True,
        time_conditioning: bool = True,
    ):
        super().__init__()
        self._setup(in_channels, hidden_size, num_heads, learn_sigma)
        self.action_context = action_context

        # Per-point encoders (Conv1d kernel 1 == a point-wise Linear): x 3 -> 64, action 3 -> 64, concatenated to
        # 128; without action context (NAC) x alone 3 -> 128. The anchor 3 -> 128 is embedded once.
        if action_context:
            self.x_embedder = nn.Linear(in_channels, hidden_size // 2)
            self.action_embedder = nn.Linear(in_channels, hidden_size - hidden_size // 2)
        else:
            self.x_embedder = nn.Linear(in_channels, hidden_size)
            self.action_embedder = None
        self.anchor_embedder = nn.Linear(in_channels, hidden_size)
        self._make_conditioning(time_conditioning)

        self.blocks = nn.ModuleList([DiTCrossBlock(hidden_size, num_heads, mlp_ratio) for _ in range(depth)])
        self.final_layer = FinalLayer(hidden_size, self.out_channels)
        self.initialize_weights()

    def forward(
        self,
        x: torch.Tensor,
        t: torch.Tensor | None,
        action: torch.Tensor | None,
        anchor: torch.Tensor,
    ) -> torch.Tensor:
        """x: (B, N, 3) noised input; t: (B,) timesteps (None without time conditioning);
        action: (B, N, 3) action context in the action frame (None for NAC); anchor: (B, M, 3) in the anchor frame.
        Returns (B, N, out_channels)."""
        B = x.shape[0]
        h = self.x_embedder(x)  # (B, N, D/2), or (B, N, D) without action context
        if self.action_embedder is not None:
            if action is None:
                raise ValueError("this network takes the action context: pass action, shape (B, N, 3)")
            h = torch.cat([h, self.action_embedder(action)], dim=-1)  # (B, N, D)
        y = self.anchor_embedder(anchor)  # (B, M, D)
        c = self.conditioning(t, B, h)  # (B, D)
        for block in self.blocks:
            h = block(h, y, c)  # (B, N, D)
        return self.final_layer(h, c)  # (B, N, out_channels)


class DiTPointCloudScene(_PointDiT):
    """Scene variants SD/SP: one action+anchor cloud, input [x_t, x_0], self-attention-only blocks."""

    def __init__(
        self,
        in_channels: int = 3,
        hidden_size: int = 128,
        depth: int = 5,
        num_heads: int = 4,
        mlp_ratio: float = 4.0,
        learn_sigma: bool = True,
        time_conditioning: bool = True,
    ):
        super().__init__()
        self._setup(in_channels, hidden_size, num_heads, learn_sigma)

        # [x_t, x_0] -> Conv1d(6 -> 128) in docs/reference.md, Model; a point-wise Linear here
        self.x_embedder = nn.Linear(2 * in_channels, hidden_size)
        self._make_conditioning(time_conditioning)

        self.blocks = nn.ModuleList([DiTSelfBlock(hidden_size, num_heads, mlp_ratio) for _ in range(depth)])
        self.final_layer = FinalLayer(hidden_size, self.out_channels)
        self.initialize_weights()

    def forward(self, x: torch.Tensor, t: torch.Tensor | None, scene: torch.Tensor) -> torch.Tensor:
        """x: (B, N+M, 3) noised scene input; t: (B,) timesteps; scene: (B, N+M, 3) clean scene points x_0.
        Returns (B, N+M, out_channels)."""
        B = x.shape[0]
        h = self.x_embedder(torch.cat([x, scene], dim=-1))  # (B, N+M, D)
        c = self.conditioning(t, B, h)  # (B, D)
        for block in self.blocks:
            h = block(h, c)  # (B, N+M, D)
        return self.final_layer(h, c)  # (B, N+M, out_channels)
