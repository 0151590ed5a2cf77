"""The torch device a command runs on, from its `--device`-style option (auto, cpu, cuda or cuda:K), and the preset
that fits the machine where none is named."""

from __future__ import annotations

import sys

import torch

from tax3d.errors import UsageError


def pick_device(name: str, option: str = "--device") -> torch.device:
    """auto: CUDA when there is one, else the CPU. A one-line UsageError for a name torch cannot use here."""
    if name == "auto":
        return torch.device("cuda" if torch.cuda.is_available() else "cpu")
    if name not in ("cpu", "cuda") and not (name.startswith("cuda:") and name[5:].isdigit()):
        raise UsageError(f"{option} {name!r}: expected auto, cpu, cuda or cuda:K")
    if name != "cpu" and not torch.cuda.is_available():
        raise UsageError(f"{option} {name}: no CUDA device is available")
    if name.startswith("cuda:") and int(name[5:]) >= torch.cuda.device_count():
        raise UsageError(f"{option} {name}: only {torch.cuda.device_count()} CUDA devices are visible")
    return torch.device(name)


def machine_preset(name: str | None, without_gpu: str) -> str:
    """The preset asked for, or the one that fits this machine: paper with a CUDA GPU, `without_gpu` without (said
    on stderr)."""
    if name is not None:
        return name
    name = "paper" if torch.cuda.is_available() else without_gpu
    print(f"--preset not given: using {name} ({'a CUDA GPU is' if name == 'paper' else 'no CUDA GPU is'} "
          f"available)", file=sys.stderr)
    return name
