"""The checkpoint directory shared by every model here: config.json + model.safetensors, checked in one line."""

from __future__ import annotations

import hashlib
import json
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


def sha256(path: Path) -> str:
    digest = hashlib.sha256()
    with open(path, "rb") as file:
        for block in iter(lambda: file.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def with_weights_hash(config: dict, directory: Path) -> dict:
    """config.json's dict with the sha256 of the directory's weights file, checked by read_weights."""
    return {**config, "weights_sha256": sha256(directory / WEIGHTS_NAME)}


def read_weights(directory: Path, map_location="cpu") -> dict:
    """The weights of a checkpoint directory; when its config.json records their sha256, it must match."""
    try:
        expected = json.loads((directory / CONFIG_NAME).read_text()).get("weights_sha256")
    except (OSError, ValueError, AttributeError):
        expected = None
    if expected is not None and sha256(directory / WEIGHTS_NAME) != expected:
        raise CheckpointError(f"{directory / WEIGHTS_NAME}: the file's sha256 differs from the one recorded in "
                              f"{CONFIG_NAME}; expected the weights saved with it (the file is damaged or replaced)")
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
