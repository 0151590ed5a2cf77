"""The checkpoint directory shared by every model here: config.json + model.safetensors, checked in one line."""

from __future__ import annotations

from pathlib import Path

import torch.nn as nn
from safetensors.torch import load_file

from tax3d.errors import UsageError

CONFIG_NAME = "config.json"
WEIGHTS_NAME = "model.safetensors"


class CheckpointError(UsageError):
    """A checkpoint directory that is missing, incomplete, or does not match its configuration."""


def check_directory(directory) -> Path:
    directory = Path(directory)
    if not directory.is_dir():
        raise CheckpointError(f"{directory}: no such checkpoint directory")
    for name in (CONFIG_NAME, WEIGHTS_NAME):
        if not (directory / name).is_file():
            raise CheckpointError(f"{directory}: incomplete checkpoint, {name} is missing")
    return directory


def read_weights(directory: Path, map_location="cpu") -> dict:
    try:
        return load_file(str(directory / WEIGHTS_NAME), device=str(map_location))
    except Exception as err:  # safetensors raises its own error types for corrupt headers
        raise CheckpointError(f"{directory / WEIGHTS_NAME}: unreadable weights ({err})") from None


def load_checked(module: nn.Module, state: dict, where: str = "weights") -> None:
    """module.load_state_dict(state), with a one-line error when the weights do not fit the configuration."""
    expected = module.state_dict()
    missing = sorted(set(expected) - set(state))
    unexpected = sorted(set(state) - set(expected))
    wrong = sorted(k for k in set(expected) & set(state) if expected[k].shape != state[k].shape)
    if missing or unexpected or wrong:
        detail = (f"missing {missing[:3]}" if missing else f"unexpected {unexpected[:3]}" if unexpected
                  else f"{wrong[0]} has shape {tuple(state[wrong[0]].shape)}, "
                       f"expected {tuple(expected[wrong[0]].shape)}")
        raise CheckpointError(f"{where}: weights do not match config.json ({detail})")
    module.load_state_dict(state)
