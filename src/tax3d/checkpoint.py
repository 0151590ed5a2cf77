"""Checkpoints: a model folder (config.json + model.safetensors, checked in one line), a run's last/ and best/."""

from __future__ import annotations

import hashlib
import io
import json
import shutil
import tempfile
from pathlib import Path

import torch

import torch.nn as nn
from safetensors.torch import load_file

from tax3d.atomic import WriteError, write_bytes, write_text, writing
from tax3d.errors import UsageError

CONFIG_NAME = "config.json"
WEIGHTS_NAME = "model.safetensors"
STATE_NAME = "training_state.pt"  # what resuming needs beside the weights (optimizer, step, generator states)


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


WEIGHT_FIELDS = {
    "model": ("variant", "hidden_size", "depth", "num_heads", "mlp_ratio"),
    "diffusion": ("num_timesteps", "learn_sigma", "prediction", "sample_steps", "sampler"),
    "data": ("num_action_points", "num_anchor_points"),
}
"""what a checkpoint's weights mean only with: the network's shape and variant (its frames), the diffusion schedule,
what the network outputs and how it samples by default, the number of points it learned on (SD/SP's frame origin,
the default subsample). A default in its place would predict, and wrongly; every other field may take its default."""


def check_fields(config: dict, where: str) -> None:
    """A CheckpointError naming the first of WEIGHT_FIELDS that a checkpoint's config.json lacks."""
    for section, names in WEIGHT_FIELDS.items():
        values = config.get(section) if isinstance(config, dict) else None
        for name in names:
            if not isinstance(values, dict) or name not in values:
                raise CheckpointError(f"{where}: no {section}.{name}; expected the value its weights were trained "
                                      f"with (a checkpoint's config.json records {section}.{', '.join(names)})")


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


# --- a training run's folder: last/ and best/, written atomically, and its log ---------------------------------

def save_checkpoint(out: Path, name: str, model: nn.Module, weights: dict, state: dict | None) -> None:
    """Write OUT/name atomically: a temporary folder beside it, then two renames (the old one kept until then).
    Weights that are not all finite are an error, never a checkpoint."""
    broken = next((k for k, v in weights.items() if v.is_floating_point() and not torch.isfinite(v).all()), None)
    if broken is not None:
        raise UsageError(f"--out {out}: weight {broken} is not finite; expected finite weights, "
                         f"{out / name} is left as it was")
    final, old = out / name, out / f".{name}.old"
    with writing(final):
        tmp = Path(tempfile.mkdtemp(prefix=f".{name}.", dir=out))
    try:
        tmp.chmod(0o755)
        model.save_pretrained(tmp, state_dict=weights)
        if state is not None:
            buffer = io.BytesIO()  # serialised here and written by Python: a full disk is then an OSError
            torch.save(state, buffer)
            write_bytes(tmp / STATE_NAME, buffer.getvalue())
    except BaseException as err:
        shutil.rmtree(tmp, ignore_errors=True)
        if isinstance(err, OSError):
            raise WriteError(err, final / getattr(err, "path", final).name) from None
        raise
    with writing(final):
        if old.exists():
            shutil.rmtree(old)
        if final.exists():
            final.rename(old)
        tmp.rename(final)
        if old.exists():
            shutil.rmtree(old)


class RunLog:
    """A run's log.jsonl: one JSON record a line, each flushed as it comes (a failed write names the file)."""

    def __init__(self, path: Path, append: bool):
        self.path = path
        with writing(path):
            self.file = open(path, "a" if append else "w")

    def write(self, record: dict) -> None:
        with writing(self.path):
            self.file.write(json.dumps(record) + "\n")
            self.file.flush()

    def close(self) -> None:
        try:
            self.file.close()
        except OSError:  # a flush that failed has been reported where it failed
            pass


def find_last(out: Path) -> Path | None:
    """OUT/last, or the previous one when a kill came between the two renames of save_checkpoint."""
    for name in ("last", ".last.old"):
        if (out / name / STATE_NAME).is_file():
            return out / name
    return None


def read_log(path: Path) -> list[dict]:
    """The records of a run's log.jsonl, one per logged step; a last line cut short (a full disk) is left out."""
    return [json.loads(line) for line in log_lines(path)]


def log_lines(path: Path) -> list[str]:
    text = path.read_text()
    lines = [line for line in text.splitlines() if line.strip()]
    return lines[:-1] if lines and not text.endswith("\n") else lines


def truncate_log(path: Path, step: int) -> None:
    """Drop log lines written after the checkpoint a run resumes from (they will be written again)."""
    if not path.is_file():
        return
    lines = [line for line in log_lines(path) if json.loads(line)["step"] <= step]
    write_text(path, "".join(line + "\n" for line in lines))
