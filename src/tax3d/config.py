"""Typed configuration: model, diffusion, data and training settings, and the named presets `paper`, `cpu`,
`cpu-multimodal` and `cpu-fast`.

A run's configuration is a `Config`; presets are complete configs, and the command line overrides single fields
with dotted options (`--model.variant cp --train.steps 2000`). Every run writes its resolved config as JSON next
to its output, and a checkpoint's `config.json` is the same JSON.
"""

from __future__ import annotations

import dataclasses
import json
import types
import typing
from dataclasses import dataclass, field
from pathlib import Path
from typing import Annotated, Literal, Optional

import tyro

from tax3d.atomic import write_text
from tax3d.errors import UsageError
from tax3d.options import Check, Fraction, NonNegative, Positive, field_docs, problems
from tax3d.variants import variant_spec


# the scaled linear schedule's last beta, 20 / T, must stay below 1
Timesteps = Check(lambda v: isinstance(v, int) and v >= 21, "at least 21 (the scaled linear schedule's last beta, "
                                                            "20 / T, must stay below 1)")


@dataclass
class ModelConfig:
    """The predictor: which variant, and the size of its DiT."""

    variant: str = "cd"
    """cd, cp, cd_w, cp_w, cd_nac, cp_nac, sd, sp, rd or rp (paper Sec. 4; CD-W and cd_w are the same)"""
    hidden_size: Annotated[int, Positive] = 128
    """width of the DiT's tokens (a multiple of num_heads)"""
    depth: Annotated[int, Positive] = 5
    """number of DiT blocks"""
    num_heads: Annotated[int, Positive] = 4
    """attention heads per block"""
    mlp_ratio: Annotated[float, Positive] = 4.0
    """width of each block's MLP, times hidden_size"""

    def conflicts(self):
        if self.hidden_size % self.num_heads:
            yield "hidden_size", self.hidden_size, f"expected a multiple of model.num_heads ({self.num_heads})"


@dataclass
class DiffusionConfig:
    """The diffusion process (docs/reference.md, Diffusion) and the default sampler of `predict`."""

    num_timesteps: Annotated[int, Timesteps] = 100
    """diffusion steps of the training schedule (at least 21)"""
    learn_sigma: bool = True
    """the network also predicts each step's variance (trained with the variational bound term)"""
    prediction: Literal["epsilon", "sample"] = "epsilon"
    """what the network outputs: the noise (the paper) or the clean target x_0, turned into the noise
    estimate eps = (x_t / sqrt(abar_t) - x_0) / sqrt(1 / abar_t - 1) so that loss and samplers are unchanged"""
    loss: Literal["epsilon", "x0", "v"] = "epsilon"
    """the mean term of the loss: the epsilon MSE (the paper's: the x_0 error weighted by SNR(t)), or the x_0 MSE
    weighted by 1 (x0) or SNR(t) + 1 (v); docs/training.md measures them"""
    sample_steps: Annotated[int, Positive] = 100
    """denoising steps at prediction: fewer than num_timesteps respaces the schedule"""
    sampler: Literal["ddpm", "ddim"] = "ddpm"
    """the default sampler of prediction: ddpm (the paper's) or ddim (deterministic)"""

    def conflicts(self):
        if self.sample_steps > self.num_timesteps:
            yield "sample_steps", self.sample_steps, f"expected at most diffusion.num_timesteps ({self.num_timesteps})"


@dataclass
class DataConfig:
    """Demonstration folders and how samples are drawn from them (docs/reference.md, Training)."""

    train: tuple[str, ...] = ()
    """training demo folders (or demo files)"""
    val: tuple[str, ...] = ()
    """validation demo folders; none: no validation and no best checkpoint"""
    num_action_points: Annotated[int, Positive] = 512
    """action points sampled (farthest point sampling) per training sample"""
    num_anchor_points: Annotated[int, Positive] = 512
    """anchor points sampled per training sample"""
    predict_points: Annotated[Optional[int], NonNegative] = None
    """action points the network sees at prediction, farthest-point sampled, every other point moving with its
    nearest ones: the default of `predict --max-points` and `eval --max-points` (none: num_action_points; 0: all)"""
    train_size: Annotated[int, Positive] = 400
    """samples per epoch (demos are repeated); an epoch holds every demo at least once"""
    subsets: Annotated[int, NonNegative] = 0
    """farthest-point subsets sampled once per demo, an item picking one at random (0: sample afresh each time)"""
    rotate: bool = True
    """rotate anchor and goal about z by U(0, 2 pi) in training (App. B)"""
    rotate_scene: bool = False
    """rotate the whole scene (action, anchor and goal) about z through the anchor mean by U(0, 2 pi) in training, as
    the authors' release does (random_flat_upright)"""
    occlusion: Annotated[float, Fraction] = 0.0
    """the chance that a training sample's action cloud loses a ball- or plane-shaped part, as a camera's view would
    (the authors' release does so for real clouds); the hidden points are refilled by repeats of the seen ones"""
    grip_weight: Annotated[float, Positive] = 1.0
    """the loss weight of the grasped vertices (where the policy's grippers go) against 1 for every other point"""
    task: str = ""
    """the task the demonstrations come from, recorded so that evaluation can check it (default: the task the demo
    files name, or custom where they name none)"""


@dataclass
class ScheduleConfig:
    """The optimiser and its schedule: the first fields of the train section of TAX3D and of DP3 alike."""

    lr: Annotated[float, Positive] = 1e-4
    """peak learning rate of AdamW, after the warm-up"""
    weight_decay: Annotated[float, NonNegative] = 1e-5
    """AdamW's weight decay"""
    warmup_steps: Annotated[int, NonNegative] = 100
    """steps of linear warm-up before the cosine decay"""
    batch_size: Annotated[int, Positive] = 16
    """samples per step (the global batch, shared among processes under torchrun)"""


@dataclass
class TrainConfig(ScheduleConfig):
    """The optimiser, schedule, validation and bookkeeping of a training run."""

    grad_clip: Annotated[float, NonNegative] = 1.0
    """clip the gradient norm to this (0: no clipping)"""
    steps: Annotated[int, Positive] = 500_000
    """optimizer steps of the run; the cosine decay ends at the last"""
    seed: int = 42
    """seed of the weights, the batches and the diffusion noise"""
    val_every: Annotated[int, Positive] = 5000
    """validate and write last/ every this many steps (and at the end)"""
    val_samples: Annotated[int, Positive] = 5
    """samples per validation demo for the min-of-samples RMSE"""
    val_demos: Annotated[int, NonNegative] = 0
    """validate on the first this many val demos (0: all)"""
    val_points: Literal["whole", "sampled"] = "whole"
    """the network's input at validation: the whole clouds, or the farthest-point sample that `predict` takes by
    default (data.predict_points), its displacements spread to every point (the RMSE is on whole clouds either way)"""
    minutes: Annotated[float, NonNegative] = 0.0
    """plan the run to end after this many minutes on this machine: the step rate measured over the first steps
    fixes train.steps (and so the cosine schedule) then, timed again at every validation (tax3d.training.budget); config.json
    records the planned steps (0: use steps)"""
    keep_every: Annotated[int, NonNegative] = 0
    """also keep the weights of each validation at a multiple of this many steps, in OUT/steps/STEP (a curve's
    checkpoints, to score later; 0: only best/ and last/)"""
    validations: Annotated[int, NonNegative] = 0
    """with train.minutes: validate this many times, evenly over the planned steps (0: every val_every steps)"""
    ema: Annotated[float, Fraction] = 0.0
    """decay of an exponential moving average of the weights (0: off); checkpoints then hold the average"""
    num_workers: Annotated[int, NonNegative] = 0
    """data loading processes (0: in the training process); the samples do not depend on it"""
    threads: Annotated[int, NonNegative] = 0
    """torch CPU threads (0: torch's default)"""
    device: str = "auto"
    """auto (cuda when available), cpu or cuda"""
    precision: Literal["fp32", "bf16"] = "fp32"
    """bf16: the network's forward under bfloat16 autocast (weights, optimizer and diffusion maths stay fp32); on a
    CPU it is slower (benchmarks/train_step.py)"""
    compile: bool = False
    """torch.compile the training loss (network and diffusion maths; the first steps wait for the compiler): the
    same maths in fewer, fused kernels (benchmarks/train_step.py)"""


@dataclass
class Config:
    model: ModelConfig = field(default_factory=ModelConfig)
    diffusion: DiffusionConfig = field(default_factory=DiffusionConfig)
    data: DataConfig = field(default_factory=DataConfig)
    train: TrainConfig = field(default_factory=TrainConfig)


def paper() -> Config:
    """The paper's settings (App. B; docs/reference.md, Model / Diffusion / Training): ~500k steps, for a GPU.

    Six data workers: in-process loading held one H100 to 6 steps per second, six workers to 29 (docs/scaling.md);
    the samples do not depend on the number of workers."""
    return Config(train=TrainConfig(num_workers=6))


def cpu() -> Config:
    """The CPU recipe for HangProcCloth-simple and -unimodal and HangBag, a run planned with --train.minutes on one
    core; docs/training.md measures its differences from `paper` (the v weighting, a smaller DiT on 256 + 256
    points, the grasped vertices weighted 16 in the loss, an EMA of the weights) and says which were chosen in runs
    not kept (x_0 prediction, a ten-times learning rate); six validations on 20 val demos."""
    return Config(
        model=ModelConfig(hidden_size=64, depth=3, num_heads=4),
        diffusion=DiffusionConfig(prediction="sample", loss="v"),
        data=DataConfig(num_action_points=256, num_anchor_points=256, rotate=False, subsets=32, grip_weight=16.0),
        train=TrainConfig(lr=1e-3, steps=4000, val_every=500, val_samples=2, val_demos=20, validations=6, threads=1,
                          num_workers=1, ema=0.999),
    )


def cpu_multimodal() -> Config:
    """`cpu` with the plain x_0 loss for HangProcCloth-multimodal: two goals per cloth, and the v weighting's stress
    on the quiet steps samples between them (docs/training.md)."""
    config = cpu()
    config.diffusion.loss = "x0"
    return config


def cpu_fast() -> Config:
    """`cpu` at batch 8 on 128 + 128 points, the network on 256 action points at prediction and validation: twice the
    samples a second; in half an hour it matched the `cpu` hour's success on HangProcCloth-unimodal and HangBag, and
    its validation RMSE on unimodal (docs/results/training-speed.md). Without a --train.minutes plan its steps take
    about half `cpu`'s time."""
    config = cpu()
    config.data.num_action_points = config.data.num_anchor_points = 128
    config.data.predict_points = 256
    config.train.batch_size = 8
    config.train.steps, config.train.val_every = 8000, 1000
    config.train.val_points = "sampled"
    return config


PRESETS = {"paper": paper, "cpu": cpu, "cpu-multimodal": cpu_multimodal, "cpu-fast": cpu_fast}
PresetName = Literal["paper", "cpu", "cpu-multimodal", "cpu-fast"]
"""the names of PRESETS, as a command-line option's type"""
TASK_PRESETS = {"hangproccloth-multimodal": "cpu-multimodal"}
"""the CPU preset of a task where it is not `cpu`"""


def cpu_preset_of(task: str) -> str:
    return TASK_PRESETS.get(task, "cpu")


def preset(name: str) -> Config:
    if name not in PRESETS:
        raise UsageError(f"--preset {name!r}: unknown preset; expected one of {', '.join(PRESETS)}")
    return PRESETS[name]()


# --- serialisation ---------------------------------------------------------------------------------------------

METADATA = ("weights_sha256", "extent")
"""top-level keys of a checkpoint's config.json beside the sections"""
_SECTIONS = {"model": ModelConfig, "diffusion": DiffusionConfig, "data": DataConfig, "train": TrainConfig}
RUN_STATE = object()
RETIRED = {("model", "mean_input"): False, ("data", "target_scale"): 1.0,
           ("train", "replan_step"): RUN_STATE, ("train", "replan_progress"): RUN_STATE,
           ("train", "time_limit"): RUN_STATE}
"""fields of earlier versions' config.json, by the value at which each changes nothing: accepted there and dropped,
any other value an error naming the field. RUN_STATE marks a field that said only where a run stopped, not what it
computed, accepted at any value and dropped: the knee of a re-planned --train.minutes run (kept in the training
state now, tax3d.training.budget), and train.time_limit (a run is stopped partway with SIGINT or SIGTERM now)."""
RETIRED_LOSSES = ("min_snr", "v_capped")
"""diffusion.loss values of earlier versions"""


def to_dict(config: Config) -> dict:
    return dataclasses.asdict(config)


def from_dict(data: dict, where: str = "config") -> Config:
    """A Config from its JSON dict, every section present; unknown sections or fields are an error naming them
    (a field left out of a section takes its default). Other top-level keys are checkpoint metadata."""
    if not isinstance(data, dict):
        raise UsageError(f"{where}: expected a JSON object with sections {', '.join(_SECTIONS)}")
    missing = [name for name in _SECTIONS if name not in data]
    if missing:
        raise UsageError(f"{where}: no '{missing[0]}' section; expected the sections {', '.join(_SECTIONS)}")
    return validate(Config(**parse_sections(without_retired(data, where), _SECTIONS, where, ignore=METADATA)), where)


def without_retired(data: dict, where: str) -> dict:
    """data without the RETIRED fields; a retired field at a value other than its neutral one is an error."""
    data = {name: dict(values) if name in _SECTIONS and isinstance(values, dict) else values
            for name, values in data.items()}
    for (section, name), neutral in RETIRED.items():
        values = data.get(section)
        if not isinstance(values, dict):
            continue
        if name in values and neutral is not RUN_STATE and values[name] != neutral:
            raise UsageError(f"{where}: {section}.{name} is {values[name]!r}: that option was retired; a config "
                             f"from an earlier version loads only with {section}.{name} = {neutral!r}")
        values.pop(name, None)
    loss = data["diffusion"].get("loss") if isinstance(data.get("diffusion"), dict) else None
    if loss in RETIRED_LOSSES:
        raise UsageError(f"{where}: diffusion.loss is {loss!r}: that loss was retired; expected one of "
                         f"{', '.join(map(repr, typing.get_args(typing.get_type_hints(DiffusionConfig)['loss'])))}")
    return data


def parse_sections(data: dict, sections: dict, where: str, ignore=()) -> dict:
    """{name: section dataclass} from a config's JSON dict; unknown sections or fields are an error naming them.
    Lists become tuples; the keys in `ignore` (such as a "kind" tag) are skipped."""
    unknown = set(data) - set(sections) - set(ignore)
    if unknown:
        raise UsageError(f"{where}: unknown sections {sorted(unknown)}; expected {', '.join(sections)}")
    out = {}
    for name, cls in sections.items():
        values = dict(data.get(name, {}))
        names = {f.name for f in dataclasses.fields(cls)}
        if set(values) - names:
            raise UsageError(f"{where}: unknown fields {sorted(set(values) - names)} in section '{name}'")
        hints = typing.get_type_hints(cls)
        for key, value in values.items():
            if not _has_type(value, hints[key]):
                raise UsageError(f"{where}: {name}.{key} is {value!r}; expected {_type_name(hints[key])}")
        out[name] = cls(**{k: tuple(v) if isinstance(v, list) else v for k, v in values.items()})
    return out


def _has_type(value, hint) -> bool:
    """Whether a JSON value fits a field's type (int, float, bool, str, a Literal, a tuple of str)."""
    origin, args = typing.get_origin(hint), typing.get_args(hint)
    if origin is Literal:
        return value in args
    if origin is tuple:
        if not isinstance(value, (list, tuple)):
            return False
        if len(args) == 2 and args[1] is Ellipsis:
            return all(_has_type(v, args[0]) for v in value)
        return len(value) == len(args) and all(_has_type(v, a) for v, a in zip(value, args))
    if origin in (typing.Union, types.UnionType):
        return any(_has_type(value, a) for a in args)
    if hint is type(None):
        return value is None
    if hint is bool:
        return isinstance(value, bool)
    if hint is int:
        return isinstance(value, int) and not isinstance(value, bool)
    if hint is float:
        return isinstance(value, (int, float)) and not isinstance(value, bool)
    return isinstance(value, hint)


def _type_name(hint) -> str:
    if typing.get_origin(hint) is Literal:
        return "one of " + ", ".join(map(repr, typing.get_args(hint)))
    if typing.get_origin(hint) is tuple:
        return "a list" + ("" if typing.get_args(hint)[-1] is Ellipsis else f" of {len(typing.get_args(hint))}")
    return {int: "an integer", float: "a number", bool: "true or false", str: "a string"}.get(hint, str(hint))


def read_json(path) -> dict:
    """A config file's JSON, with a one-line error naming the file when it cannot be read."""
    path = Path(path)
    try:
        return json.loads(path.read_text())
    except (OSError, json.JSONDecodeError) as err:
        raise UsageError(f"{path}: unreadable config ({err})") from None


def save(config: Config, path) -> None:
    write_text(path, json.dumps(to_dict(config), indent=2) + "\n")


def load(path) -> Config:
    return from_dict(read_json(path), str(path))


def validate(config: Config, where: str = "config") -> Config:
    """The config with its variant's name normalised, once every value passes its checks (tax3d.options): a
    UsageError naming the option (where is "options") or the field of the file `where` otherwise."""
    for name, value, problem in problems(config):
        raise UsageError(f"--{name.replace('_', '-')} {value}: {problem}" if where == "options"
                         else f"{where}: {name} = {value!r}: {problem}")
    config.model.variant = variant_spec(config.model.variant).name
    return config


# --- command-line overrides ------------------------------------------------------------------------------------


def overrides_of(cls: type) -> type:
    """A dataclass with cls's fields, each optional and None by default: None keeps the preset's value. Each keeps
    its field's docstring as its --help."""
    hints = typing.get_type_hints(cls)
    docs = field_docs(cls)
    fields = []
    for f in dataclasses.fields(cls):
        own = "(default:" in docs.get(f.name, "")  # a field whose docstring gives its default shows it once
        arg = tyro.conf.arg(help=docs.get(f.name, ""), help_behavior_hint="" if own else "(default: the preset's)")
        fields.append((f.name, Annotated[Optional[hints[f.name]], arg], field(default=None)))
    made = dataclasses.make_dataclass(f"{cls.__name__}Overrides", fields, frozen=True)
    # The field docs again as a docstring's "Args:" section, where tyro looks first: without it, every parse
    # searches config.py's syntax tree for a class that has no source: three times the cost of the parse.
    made.__doc__ = "\n\nArgs:\n" + "".join(
        f"    {f.name}: {docs.get(f.name) or f.name}\n" for f in dataclasses.fields(cls))
    return made


ModelOverrides = overrides_of(ModelConfig)
DiffusionOverrides = overrides_of(DiffusionConfig)
DataOverrides = overrides_of(DataConfig)
TrainOverrides = overrides_of(TrainConfig)


def apply_overrides(config: Config, **sections) -> Config:
    """config with every non-None field of the given override sections (model=..., data=...) replaced."""
    replaced = {}
    for name, overrides in sections.items():
        current = getattr(config, name)
        values = {k: v for k, v in dataclasses.asdict(overrides).items() if v is not None}
        replaced[name] = dataclasses.replace(current, **values)
    return dataclasses.replace(config, **replaced)
