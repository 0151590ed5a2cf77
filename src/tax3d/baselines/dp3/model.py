"""DP3: a point-cloud-conditioned diffusion policy over absolute gripper targets (docs/reference.md, "DP3 baseline").

    model = DP3.from_pretrained("runs/dp3/last")
    actions = model.predict_action(points, state)   # (B, horizon, 6) world-frame gripper targets

A checkpoint is a directory with config.json ("kind": "dp3") and model.safetensors; the weights include the
normalisers' limits.
"""

from __future__ import annotations

from pathlib import Path

import torch
import torch.nn as nn
import torch.nn.functional as F
from safetensors.torch import save as safetensors_bytes

from tax3d.atomic import write_bytes, write_text
from tax3d.baselines.dp3 import config as cfg
from tax3d.baselines.dp3.network import ConditionalUnet1D, ObservationEncoder
from tax3d.baselines.dp3.normalizer import MinMaxNormalizer
from tax3d.baselines.dp3.scheduler import DDIM
from tax3d.checkpoint import CONFIG_NAME, WEIGHTS_NAME, check_directory, load_checked, read_weights

STATE_DIM = 12  # two grippers' positions and velocities (docs/reference.md, "DP3 baseline")
ACTION_DIM = 6  # two absolute gripper targets


class DP3(nn.Module):
    """Observation encoder + conditional UNet + DDIM, on inputs scaled to [-1, 1]."""

    def __init__(self, config: cfg.DP3Config):
        super().__init__()
        self.config = cfg.validate(config)
        m, d = config.model, config.diffusion
        self.encoder = ObservationEncoder(STATE_DIM, m.point_dims, m.encoder_dim, m.state_dims)
        self.unet = ConditionalUnet1D(ACTION_DIM, self.encoder.out_dim * m.n_obs_steps, m.down_dims,
                                      m.step_embed_dim, m.kernel_size, m.groups)
        self.normalizers = nn.ModuleDict({"points": MinMaxNormalizer(3), "state": MinMaxNormalizer(STATE_DIM),
                                          "action": MinMaxNormalizer(ACTION_DIM)})
        self.scheduler = DDIM(d.train_steps, d.inference_steps, d.clip_sample)

    @property
    def device(self) -> torch.device:
        return next(self.parameters()).device

    def fit_normalizers(self, points: torch.Tensor, state: torch.Tensor, action: torch.Tensor) -> None:
        """Limits from training data (..., 3), (..., 12), (..., 6); rotation-proof in x, y when training rotates."""
        rotate = self.config.data.rotate
        for name, data in (("points", points), ("state", state), ("action", action)):
            self.normalizers[name].fit(data, rotation_invariant=rotate)

    def condition(self, points: torch.Tensor, state: torch.Tensor) -> torch.Tensor:
        """Normalised points (B, To, N, 3) and state (B, To, 12) -> the global condition (B, To * 128)."""
        batch, steps = state.shape[:2]
        features = self.encoder(points.flatten(0, 1), state.flatten(0, 1))  # (B To, D)
        return features.reshape(batch, steps * features.shape[-1])  # concatenated over observation steps

    def _normalised(self, batch: dict) -> tuple[torch.Tensor, ...]:
        n = self.normalizers
        return n["points"].normalize(batch["points"]), n["state"].normalize(batch["state"])

    def loss(self, batch: dict, t: torch.Tensor | None = None, noise: torch.Tensor | None = None) -> torch.Tensor:
        """MSE between the network's x_0 and the normalised action window (sample prediction)."""
        points, state = self._normalised(batch)
        action = self.normalizers["action"].normalize(batch["action"])  # (B, H, 6)
        if t is None:
            t = torch.randint(self.scheduler.train_steps, (action.shape[0],), device=action.device)
        if noise is None:
            noise = torch.randn_like(action)
        noisy = self.scheduler.add_noise(action, noise, t)
        return F.mse_loss(self.unet(noisy, t, self.condition(points, state)), action)

    @torch.no_grad()
    def predict_action(self, points: torch.Tensor, state: torch.Tensor,
                       generator: torch.Generator | None = None) -> torch.Tensor:
        """World-frame action windows (B, horizon, 6) for points (B, To, N, 3) and state (B, To, 12)."""
        points, state = self._normalised({"points": points.to(self.device), "state": state.to(self.device)})
        cond = self.condition(points, state)
        shape = (cond.shape[0], self.config.model.horizon, ACTION_DIM)
        action = self.scheduler.sample(lambda x, t: self.unet(x, t, cond), shape, generator, self.device)
        return self.normalizers["action"].unnormalize(action)

    # --- checkpoints -----------------------------------------------------------------------------------------------

    def save_pretrained(self, directory, state_dict: dict | None = None) -> None:
        """Write config.json and model.safetensors into `directory` (created; files replaced atomically)."""
        directory = Path(directory)
        directory.mkdir(parents=True, exist_ok=True)
        state = {k: v.detach().to("cpu").contiguous() for k, v in (state_dict or self.state_dict()).items()}
        write_bytes(directory / WEIGHTS_NAME, safetensors_bytes(state, metadata={"format": "pt"}))
        write_text(directory / CONFIG_NAME, cfg.dumps(self.config))

    @classmethod
    def from_pretrained(cls, directory, map_location="cpu") -> "DP3":
        directory = check_directory(directory)
        model = cls(cfg.load(directory / CONFIG_NAME))
        model.load_weights(read_weights(directory, map_location), str(directory / WEIGHTS_NAME))
        return model.to(map_location).eval()

    def load_weights(self, state: dict, where: str = "weights") -> None:
        """Load a state dict, with a one-line error when it does not fit this configuration."""
        load_checked(self, state, where)
