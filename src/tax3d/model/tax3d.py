"""The TAX3D predictor: a variant's network and diffusion, its training loss, sampling, and a small policy API.

    model = Tax3D.from_pretrained("checkpoints/tax3d-cd-official-simple")
    goals = model.predict(action_points, anchor_points, num_samples=5)   # (5, N, 3), world frame

A checkpoint is a directory with `config.json` (a `tax3d.config.Config`) and `model.safetensors`.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import torch
import torch.nn as nn
from safetensors.torch import save as safetensors_bytes
from scipy.spatial import cKDTree

from tax3d import config as cfg
from tax3d import extent
from tax3d.atomic import write_bytes, write_text
from tax3d.checkpoint import (CONFIG_NAME, WEIGHTS_NAME, CheckpointError, check_directory, check_fields,
                              load_checked, read_weights, with_weights_hash)
from tax3d.errors import UsageError
from tax3d.frames import frame_inputs, to_world
from tax3d.geometry import farthest_point_sample
from tax3d.model.diffusion import GaussianDiffusion, linear_betas
from tax3d.model.dit import DiTPointCloudCross, DiTPointCloudScene
from tax3d.variants import variant_spec

CARRY_NEIGHBOURS = 4  # sampled points whose displacements an unsampled action point interpolates


def build_network(config: cfg.Config) -> nn.Module:
    spec = variant_spec(config.model.variant)
    m = config.model
    learn_sigma = spec.diffusion and config.diffusion.learn_sigma
    size = dict(hidden_size=m.hidden_size, depth=m.depth, num_heads=m.num_heads, mlp_ratio=m.mlp_ratio)
    if spec.scene:
        return DiTPointCloudScene(learn_sigma=learn_sigma, time_conditioning=spec.diffusion, **size)
    return DiTPointCloudCross(learn_sigma=learn_sigma, action_context=spec.action_context,
                              time_conditioning=spec.diffusion, **size)


class Tax3D(nn.Module):
    """A TAX3D variant (CD, CP, -W, NAC, SD/SP, RD/RP): network + diffusion, in the variant's frames."""

    def __init__(self, config: cfg.Config):
        super().__init__()
        self.config = cfg.validate(config)
        self.spec = variant_spec(config.model.variant)
        self.net = build_network(config)
        self.learn_sigma = self.spec.diffusion and config.diffusion.learn_sigma
        self.diffusion = GaussianDiffusion(linear_betas(config.diffusion.num_timesteps), learn_sigma=self.learn_sigma,
                                           loss=config.diffusion.loss)
        self.extent: dict | None = None  # of the training clouds (tax3d.extent); None: not recorded

    # --- the network in the variant's frames ---------------------------------------------------------------------

    def model_fn(self, action: torch.Tensor, anchor: torch.Tensor):
        """model_fn(x_t, t) for the diffusion: action (B, N, 3) and anchor (B, M, 3) in the variant's frames."""
        if self.spec.scene:
            scene = torch.cat([action, anchor], dim=1)  # (B, N + M, 3)
            return self._as_epsilon(lambda x, t: self.net(x, t, scene))
        context = action if self.spec.action_context else None
        fn = lambda x, t: self.net(x, t, context, anchor)
        return self._as_epsilon(fn) if self.spec.diffusion else fn

    def _as_epsilon(self, fn):
        if self.config.diffusion.prediction == "epsilon":
            return fn

        def eps_fn(x: torch.Tensor, t: torch.Tensor) -> torch.Tensor:
            out = fn(x, t)  # t are the model's (unrespaced) timesteps, so the base schedule applies
            eps = self.diffusion.predict_eps_from_xstart(x, t, out[..., :3])
            return torch.cat([eps, out[..., 3:]], dim=-1)

        return eps_fn

    def regress(self, action: torch.Tensor, anchor: torch.Tensor) -> torch.Tensor:
        """RD/RP: one forward pass; the network's noised input is zeros, its output the target (B, N, 3)."""
        return self.model_fn(action, anchor)(torch.zeros_like(action), None)

    def loss(self, batch: dict, t: torch.Tensor | None = None, noise: torch.Tensor | None = None) -> dict:
        """Mean training losses of a batch from `DemoDataset`: loss, mse, vb (scalars).

        Diffusion variants: the hybrid loss (docs/reference.md, Diffusion); t and noise default to fresh draws.
        RD/RP: the MSE of one regression pass, vb = 0. SD/SP diffuse the scene target (action and anchor rows)."""
        action, anchor, target = batch["action"], batch["anchor"], batch["target"]
        if not self.spec.diffusion:
            mse = ((self.regress(action, anchor) - target) ** 2).mean()
            return {"loss": mse, "mse": mse, "vb": torch.zeros_like(mse)}
        if t is None:
            t = self.diffusion.sample_timesteps(target.shape[0], target.device)
        losses = self.diffusion.training_losses(self.model_fn(action, anchor), target, t, noise,
                                                batch.get("point_weight"))
        return {k: v.mean() for k, v in losses.items()}

    def sampling(self, steps: int | None, sampler: str | None, prefix: str = "") -> tuple[int, str]:
        """The number of steps and the sampler to use (the config's by default), checked; errors name the
        arguments with `prefix` ("--" for the command line)."""
        steps = self.config.diffusion.sample_steps if steps is None else _whole(steps, "steps")
        sampler = self.config.diffusion.sampler if sampler is None else sampler
        T = self.diffusion.num_timesteps
        if not 1 <= steps <= T:
            raise UsageError(f"{prefix}steps {steps}: expected a number of denoising steps in [1, {T}]")
        if sampler not in ("ddpm", "ddim"):
            raise UsageError(f"{prefix}sampler {sampler!r}: expected ddpm or ddim")
        return steps, sampler

    @torch.no_grad()
    def sample(self, action: torch.Tensor, anchor: torch.Tensor, steps: int | None = None, sampler: str | None = None,
               generator: torch.Generator | None = None, return_trajectory: bool = False, progress=False):
        """Model outputs (B, N, 3) in the variant's frame for inputs in that frame (B, N, 3), (B, M, 3).

        With return_trajectory, also (S + 1, B, N, 3): x_T, ..., x_0 (one entry for RD/RP)."""
        if not self.spec.diffusion:
            out = self.regress(action, anchor)
            return (out, out[None]) if return_trajectory else out
        steps, sampler = self.sampling(steps, sampler)
        T = self.diffusion.num_timesteps
        diffusion = self.diffusion if steps == T else self.diffusion.respace(steps)
        n = action.shape[1] + (anchor.shape[1] if self.spec.scene else 0)
        shape = (action.shape[0], n, 3)
        loop = diffusion.p_sample_loop if sampler == "ddpm" else diffusion.ddim_sample_loop
        out = loop(self.model_fn(action, anchor), shape, generator=generator, device=action.device,
                   progress=progress, return_trajectory=return_trajectory)
        if return_trajectory:
            return out[0][:, : action.shape[1]], out[1][:, :, : action.shape[1]]
        return out[:, : action.shape[1]]

    # --- the policy API --------------------------------------------------------------------------------------------

    @property
    def device(self) -> torch.device:
        return next(self.parameters()).device

    def _points(self, points, name: str) -> torch.Tensor:
        if not isinstance(points, torch.Tensor):
            points = np.asarray(points)
            if points.dtype.kind not in "fiu":
                raise TypeError(f"{name} has dtype {points.dtype}; expected real numbers")
        elif points.is_complex() or points.dtype == torch.bool:
            raise TypeError(f"{name} has dtype {points.dtype}; expected real numbers")
        points = torch.as_tensor(points)
        if points.ndim != 2 or points.shape[1] != 3 or points.shape[0] == 0:
            raise UsageError(f"{name} has shape {tuple(points.shape)}; expected (N, 3) with N > 0")
        if not torch.isfinite(points).all():
            raise UsageError(f"{name} contains NaN or infinite values")
        return points.to(device=self.device, dtype=torch.float32)

    def _frames(self, action_points, anchor_points, generator: torch.Generator, max_points: int | None = None) -> dict:
        """The network's inputs for one scene. An action cloud of more than max_points (default:
        data.predict_points, else the training size; 0: no limit) is farthest-point sampled to it; "carry" then
        holds, for each input point, its CARRY_NEIGHBOURS nearest sampled points and their inverse-distance weights
        (`_carry`)."""
        action = self._points(action_points, "action_points")
        anchor = self._points(anchor_points, "anchor_points")
        k = self.config.data.num_anchor_points
        if anchor.shape[0] > k:
            anchor = anchor[farthest_point_sample(anchor, k, start=generator)]
        if max_points is None:
            max_points = self.config.data.predict_points
        # SD/SP: the scene frame's origin is the mean of the cloud the network trained on (that many action and
        # anchor points); a denser action cloud would move it, so these variants always take the training size
        limit = self.config.data.num_action_points if max_points is None or self.spec.scene else max_points
        carry = None
        if 0 < limit < action.shape[0]:
            full = action
            action = action[farthest_point_sample(action, limit, start=generator)]
            k = min(CARRY_NEIGHBOURS, limit)
            distance, nearest = cKDTree(action.cpu().numpy()).query(full.cpu().numpy(), k=k)
            distance, nearest = distance.reshape(len(full), k), nearest.reshape(len(full), k)
            weight = 1.0 / np.maximum(distance, 1e-9)
            weight[distance < 1e-9] = 1e9  # a point that was sampled keeps its own displacement
            weight /= weight.sum(1, keepdims=True)
            carry = {"full": full, "sampled": action, "nearest": torch.as_tensor(nearest, device=full.device),
                     "weight": torch.as_tensor(weight, dtype=full.dtype, device=full.device)}
        frames = frame_inputs(action.double(), anchor.double(), self.spec)
        frames = {key: value.float() for key, value in frames.items()}
        return {**frames, "carry": carry} if carry is not None else frames

    @staticmethod
    def _carry(goals: torch.Tensor, carry: dict | None) -> torch.Tensor:
        """World goals (..., k, 3) of the sampled points -> (..., N, 3) for every input point: each point moves by
        the inverse-distance-weighted mean displacement of its nearest sampled points."""
        if carry is None:
            return goals
        displacement = goals - carry["sampled"]
        neighbours = displacement[..., carry["nearest"], :]  # (..., N, CARRY_NEIGHBOURS, 3)
        return carry["full"] + (neighbours * carry["weight"][..., None]).sum(-2)

    def _generator(self, generator: torch.Generator | None, seed: int | None) -> torch.Generator:
        if generator is not None:
            return generator
        generator = torch.Generator(device=self.device)
        generator.manual_seed(int(seed) if seed is not None else int(torch.randint(2**62, ()).item()))
        return generator

    @torch.no_grad()
    def predict(self, action_points, anchor_points, num_samples: int = 1, steps: int | None = None,
                sampler: str | None = None, generator: torch.Generator | None = None, seed: int | None = None,
                return_trajectory: bool = False, max_points: int | None = None, progress: bool = False):
        """World-frame goal clouds (num_samples, N, 3) for action (N, 3) and anchor (M, 3) world points.

        Any N works, and the goal keeps the order of the action points. The network runs on at most
        `max_points` of them (default: data.predict_points, else the number it was trained on; 0: all; SD/SP:
        always the number it was trained on, whose mean is their frame's origin), farthest-point sampled; every
        other point moves by the inverse-distance-weighted displacement of its nearest sampled points. The anchor
        is downsampled by FPS to the trained number of points. The samples are denoised together, in one batch. numpy in, numpy out; tensors in,
        tensors out. With return_trajectory, also the denoising trajectory in the world frame, (S + 1, num_samples,
        N, 3). `seed` makes a fresh generator; `generator` is used as given. `progress` shows a bar over the
        denoising steps.
        """
        as_numpy = not isinstance(action_points, torch.Tensor)
        num_samples = _positive(num_samples, "num_samples")
        if self.spec.diffusion:
            self.sampling(steps, sampler)
        if max_points is not None:
            max_points = _whole(max_points, "max_points")
            if max_points < 0:
                raise ValueError(f"max_points is {max_points}; expected 0 (no limit) or a positive integer")
        generator = self._generator(generator, seed)
        frames = self._frames(action_points, anchor_points, generator, max_points)
        extent.warn(self.extent, [(action_points, anchor_points)])
        carry = frames.pop("carry", None)
        out = self.sample(frames["action"].expand(num_samples, -1, -1), frames["anchor"].expand(num_samples, -1, -1),
                          steps, sampler, generator, return_trajectory, progress)
        if return_trajectory:
            goals = self._carry(to_world(out[0], frames, self.spec), carry)
            trajectory = self._carry(to_world(out[1], frames, self.spec), carry)
            return (goals.cpu().numpy(), trajectory.cpu().numpy()) if as_numpy else (goals, trajectory)
        goals = self._carry(to_world(out, frames, self.spec), carry)
        return goals.cpu().numpy() if as_numpy else goals

    @torch.no_grad()
    def predict_scenes(self, scenes, num_samples: int = 1, steps: int | None = None, sampler: str | None = None,
                       seed: int = 0, batch_scenes: int = 8, progress: bool = False,
                       max_points: int | None = None) -> list[np.ndarray]:
        """predict for many (action_points, anchor_points) scenes: a list of (num_samples, N_i, 3) numpy arrays.

        Scenes with the same number of network points are denoised together, batch_scenes at a time; max_points
        as in `predict`."""
        from tqdm.auto import tqdm

        num_samples, batch_scenes = _positive(num_samples, "num_samples"), _positive(batch_scenes, "batch_scenes")
        steps_per_batch = self.sampling(steps, sampler)[0] if self.spec.diffusion else 1
        generator = self._generator(None, seed)
        frames = [self._frames(action, anchor, generator, max_points) for action, anchor in scenes]
        extent.warn(self.extent, scenes)
        carries = [f.pop("carry", None) for f in frames]
        results: list[np.ndarray | None] = [None] * len(frames)
        by_size: dict[tuple, list[int]] = {}
        for i, f in enumerate(frames):
            by_size.setdefault((f["action"].shape[0], f["anchor"].shape[0]), []).append(i)
        chunks = [indices[start:start + batch_scenes] for indices in by_size.values()
                  for start in range(0, len(indices), batch_scenes)]
        # one bar over every denoising step of every batch: a long prediction shows its progress step by step
        bar = tqdm(total=len(chunks) * steps_per_batch, desc=f"predict ({len(chunks)} batches)", unit="step",
                   disable=not progress, leave=False)
        for chunk in chunks:
            stacked = {k: torch.stack([frames[i][k] for i in chunk]).repeat_interleave(num_samples, 0)
                       for k in frames[chunk[0]]}  # (C * K, ...)
            out = self.sample(stacked["action"], stacked["anchor"], steps, sampler, generator,
                              progress=bar if progress and self.spec.diffusion else False)
            if not self.spec.diffusion:
                bar.update(1)
            goals = to_world(out, stacked, self.spec).reshape(len(chunk), num_samples, -1, 3)
            for i, g in zip(chunk, goals):
                results[i] = self._carry(g, carries[i]).cpu().numpy()
        bar.close()
        return results

    # --- checkpoints -----------------------------------------------------------------------------------------------

    def save_pretrained(self, directory, state_dict: dict | None = None) -> None:
        """Write config.json and model.safetensors into `directory` (created; files replaced atomically)."""
        directory = Path(directory)
        directory.mkdir(parents=True, exist_ok=True)
        state = state_dict if state_dict is not None else self.net.state_dict()
        state = {k: v.detach().to("cpu").contiguous() for k, v in state.items()}
        # serialised here and written by Python, so that a full disk is an OSError naming the file
        write_bytes(directory / WEIGHTS_NAME, safetensors_bytes(state, metadata={"format": "pt"}))
        config = with_weights_hash({**cfg.to_dict(self.config), **({"extent": self.extent} if self.extent else {})},
                                   directory)
        write_text(directory / CONFIG_NAME, json.dumps(config, indent=2) + "\n")

    @classmethod
    def from_pretrained(cls, directory, variant: str | None = None, map_location="cpu") -> "Tax3D":
        """Load a checkpoint directory. `variant`, when given, must be the checkpoint's."""
        directory = check_directory(directory)
        raw = cfg.read_json(directory / CONFIG_NAME)
        config = cfg.from_dict(raw, str(directory / CONFIG_NAME))  # sections and types first, then the fields
        check_fields(raw, str(directory / CONFIG_NAME))
        if variant is not None and variant_spec(variant).name != config.model.variant:
            raise CheckpointError(f"{directory}: the checkpoint is variant '{config.model.variant}', "
                                  f"not the requested '{variant_spec(variant).name}'")
        model = cls(config)
        model.extent = raw.get("extent") if isinstance(raw.get("extent"), dict) else None
        model.load_weights(read_weights(directory, map_location), str(directory / WEIGHTS_NAME))
        return model.to(map_location).eval()

    def load_weights(self, state: dict, where: str = "weights") -> None:
        """Load a network state dict, with a one-line error when it does not fit this configuration."""
        load_checked(self.net, state, where)


def _whole(value, name: str) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise TypeError(f"{name} is {value!r}; expected an integer")
    return int(value)


def _positive(value, name: str) -> int:
    value = _whole(value, name)
    if value < 1:
        raise ValueError(f"{name} is {value}; expected a positive integer")
    return value
