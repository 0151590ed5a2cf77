"""DP3 settings (docs/reference.md, "DP3 baseline"): the presets `paper` and `cpu`, and their JSON form.

A checkpoint's config.json is this JSON with "kind": "dp3", which is how `tax3d eval` tells it from a TAX3D one.
"""

from __future__ import annotations

import dataclasses
import json
from dataclasses import dataclass, field
from pathlib import Path

from tax3d.config import ScheduleConfig, overrides_of, parse_sections, read_json
from tax3d.errors import UsageError

KIND = "dp3"


@dataclass
class ModelConfig:
    """Observation encoder and conditional 1-D UNet."""

    variant: str = "dp3"
    """always dp3: the method's name in evaluation summaries"""
    horizon: int = 4
    """gripper actions predicted per sample (a window of steps)"""
    n_obs_steps: int = 2
    """observations (clouds and gripper states of the latest steps) each prediction is conditioned on"""
    n_action_steps: int = 4
    """actions executed per prediction, from the current step on"""
    point_dims: tuple[int, ...] = (64, 128, 256)
    """widths of the point encoder's per-point MLP, before its max-pool"""
    encoder_dim: int = 64
    """size of the pooled cloud feature"""
    state_dims: tuple[int, ...] = (64, 64)
    """widths of the gripper-state MLP"""
    down_dims: tuple[int, ...] = (512, 1024, 2048)
    """channels of the UNet's levels (each level halves the horizon)"""
    step_embed_dim: int = 128
    """size of the diffusion step's embedding"""
    kernel_size: int = 5
    """kernel of the UNet's 1-D convolutions (odd)"""
    groups: int = 8
    """GroupNorm groups of the UNet's convolutions"""


@dataclass
class DiffusionConfig:
    """DDIM with the squaredcos_cap_v2 schedule, sample prediction and clipping to [-1, 1]."""

    train_steps: int = 100
    """diffusion steps of the training schedule"""
    inference_steps: int = 10
    """DDIM steps at prediction"""
    clip_sample: bool = True
    """clip each step's estimate of the clean actions to [-1, 1] (the normalised range)"""


@dataclass
class DataConfig:
    """The demonstrations with trajectories and how observations are drawn from them."""

    train: tuple[str, ...] = ()
    """demo folders (or demo files) written with `tax3d generate --trajectories`"""
    num_action_points: int = 512
    """cloth points per observation (a prefix of the stored farthest-point order)"""
    num_anchor_points: int = 512
    """anchor points per observation"""
    rotate: bool = True
    """rotate points, state and actions together about the world z axis by U(0, 2 pi) in training"""
    task: str = ""
    """the task the demonstrations come from (checked by `tax3d eval`; empty: unknown)"""


@dataclass
class TrainConfig(ScheduleConfig):
    """AdamW with a warm-up and cosine decay (lr, weight_decay, warmup_steps and batch_size as for TAX3D, DP3's values
    in PAPER_SCHEDULE), an EMA of the weights, and the saves of last/."""

    steps: int = 112_500
    """optimizer steps of the run; the cosine decay ends at the last"""
    seed: int = 0
    """seed of the weights, and with the step of each step's batch, rotations and noise"""
    save_every: int = 5000
    """write last/ every this many steps (and at the end)"""
    minutes: float = 0.0
    """plan the run to end after this many minutes on this machine, as TAX3D's train.minutes, timed again at every
    save (0: use steps); the table gives DP3 the wall time of the TAX3D rows"""
    threads: int = 0
    """torch CPU threads (0: torch's default)"""


PAPER_SCHEDULE = dict(weight_decay=1e-6, warmup_steps=500, batch_size=128)
"""DP3's optimiser and schedule where they differ from TAX3D's (docs/dp3.md)"""


@dataclass
class DP3Config:
    model: ModelConfig = field(default_factory=ModelConfig)
    diffusion: DiffusionConfig = field(default_factory=DiffusionConfig)
    data: DataConfig = field(default_factory=DataConfig)
    train: TrainConfig = field(default_factory=lambda: TrainConfig(**PAPER_SCHEDULE))


def paper() -> DP3Config:
    """The DP3 of docs/reference.md ("DP3 baseline"), with DP3's own UNet widths and optimiser details.

    See docs/dp3.md.
    """
    return DP3Config()


def cpu() -> DP3Config:
    """Small enough to train for minutes and to roll out 75 predictions per episode on one CPU core."""
    return DP3Config(
        model=ModelConfig(down_dims=(64, 128, 256), step_embed_dim=64),
        data=DataConfig(num_action_points=256, num_anchor_points=256),
        train=TrainConfig(**{**PAPER_SCHEDULE, "lr": 3e-4, "warmup_steps": 50, "batch_size": 32}, steps=3000,
                          save_every=250, threads=1),
    )


PRESETS = {"paper": paper, "cpu": cpu}
# the command line's `--model.*`, `--diffusion.*`, `--data.*`, `--train.*`, as for TAX3D (tax3d.config)
ModelOverrides = overrides_of(ModelConfig)
DiffusionOverrides = overrides_of(DiffusionConfig)
DataOverrides = overrides_of(DataConfig)
TrainOverrides = overrides_of(TrainConfig)
_SECTIONS = {"model": ModelConfig, "diffusion": DiffusionConfig, "data": DataConfig, "train": TrainConfig}


def preset(name: str) -> DP3Config:
    if name not in PRESETS:
        raise UsageError(f"--preset {name!r}: unknown preset; expected one of {', '.join(PRESETS)}")
    return PRESETS[name]()


def validate(config: DP3Config, where: str = "config") -> DP3Config:
    m, d = config.model, config.diffusion
    levels = len(m.down_dims)
    checks = [
        (m.variant == "dp3", "model.variant must be dp3"),
        (m.n_obs_steps >= 1 and 1 <= m.n_action_steps <= m.horizon, "model.n_action_steps must lie in [1, horizon]"),
        (levels >= 1 and m.horizon % 2 ** (levels - 1) == 0,
         f"model.horizon must be a multiple of {2 ** (levels - 1)} (the UNet halves it {levels - 1} times)"),
        (all(w % m.groups == 0 for w in m.down_dims), "model.down_dims must be multiples of model.groups"),
        (m.kernel_size % 2 == 1, "model.kernel_size must be odd"),
        (1 <= d.inference_steps <= d.train_steps, "diffusion.inference_steps must lie in [1, diffusion.train_steps]"),
        (config.data.num_action_points >= 1 and config.data.num_anchor_points >= 1,
         "data.num_action_points and data.num_anchor_points must be positive"),
        (config.train.batch_size >= 1 and config.train.steps >= 1, "train.batch_size and train.steps must be positive"),
        (config.train.save_every >= 1, "train.save_every must be positive"),
    ]
    for ok, message in checks:
        if not ok:
            raise UsageError(f"{where}: {message}")
    return config


def to_dict(config: DP3Config) -> dict:
    return {"kind": KIND, **dataclasses.asdict(config)}


def from_dict(data: dict, where: str = "config") -> DP3Config:
    if not isinstance(data, dict) or data.get("kind") != KIND:
        raise UsageError(f"{where}: not a DP3 configuration; expected a JSON object with \"kind\": \"{KIND}\"")
    sections = parse_sections(data, _SECTIONS, where, ignore=("kind",))
    return validate(DP3Config(**sections), where)


def dumps(config: DP3Config) -> str:
    return json.dumps(to_dict(config), indent=2) + "\n"


def load(path) -> DP3Config:
    return from_dict(read_json(path), str(path))


def is_dp3_checkpoint(directory) -> bool:
    """True when directory/config.json exists and says "kind": "dp3"."""
    try:
        return json.loads((Path(directory) / "config.json").read_text()).get("kind") == KIND
    except (OSError, ValueError, AttributeError):
        return False
