"""Whether a rerun into a run's folder is the same run: the configuration its command makes against the one the
folder records, and its demonstrations against their digest (OUT/demos.json). A rerun of the same run resumes; any
other is refused, naming what differs, so that a folder's files never describe a run that did not happen."""

from __future__ import annotations

import copy
import dataclasses
import json
import shutil
from pathlib import Path

from tax3d import config as cfg
from tax3d.atomic import write_text
from tax3d.checkpoint import STATE_NAME, find_last
from tax3d.data.digest import demos_digest
from tax3d.errors import UsageError

DIGEST_NAME = "demos.json"
HOW = {("train", "num_workers"), ("train", "threads"), ("train", "device"), ("train", "compile"),
       ("train", "keep_every")}
"""fields that change how or how long a run computes, not the steps it takes: a resumed run may set them otherwise"""
PLANNED = {("train", "steps"), ("train", "val_every"), ("train", "save_every")}
"""fields a --train.minutes plan fixes at the run's start (config.json records them)"""
DERIVED = {("data", "task")}
"""fields made from the demonstrations (their digest is compared instead)"""


def checkpoint_to_resume(out: Path, resume: bool, fresh: bool) -> Path | None:
    """OUT/last when a rerun continues the run there (None: a fresh start); --resume requires one, --fresh ignores
    it."""
    if resume and fresh:
        raise UsageError("--fresh: not with --resume; expected one or the other")
    last = None if fresh else find_last(out)
    if resume and last is None:
        raise UsageError(f"--resume: {out} holds no checkpoint to continue from (expected {out / 'last' / STATE_NAME})")
    return last


def resolve(configs, preset, overrides: dict, out: Path, last: Path | None, extend: bool = False):
    """The command's configuration (`preset` with `overrides`); resuming, the run's saved one with them, after
    checking that the command's equals it (check_same_run). `configs` is the config module of the run's kind
    (tax3d.config, or DP3's), with its `validate` and `load`."""
    command = configs.validate(cfg.apply_overrides(preset, **overrides), "options")
    if last is None:
        return command
    saved = configs.load(last / "config.json")
    check_same_run(out, cfg.read_json(last / "config.json"), saved, command, extend)
    return configs.validate(cfg.apply_overrides(copy.deepcopy(saved), **overrides), "options")


def differences(recorded: dict, saved: cfg.Config, command: cfg.Config,
                extend: bool = False) -> list[tuple[str, object, object]]:
    """(section.field, the run's value, the command's) where the command's configuration differs from the run's.
    Fields that the run's config.json lacks (written before they existed) are not compared, nor, with `extend`
    (--resume), the steps and validation interval."""
    skipped = HOW | DERIVED | (PLANNED if saved.train.minutes > 0 or extend else set())
    found = []
    for section in ("model", "diffusion", "data", "train"):
        present = recorded.get(section, {})
        for f in dataclasses.fields(getattr(saved, section)):
            if (section, f.name) in skipped or f.name not in present:
                continue
            before, now = getattr(getattr(saved, section), f.name), getattr(getattr(command, section), f.name)
            if before != now:
                found.append((f"{section}.{f.name}", before, now))
    return found


def check_same_run(out: Path, recorded: dict, saved: cfg.Config, command: cfg.Config, extend: bool = False) -> None:
    """A UsageError naming the first difference (and how many more) between the run in OUT and the command's."""
    found = differences(recorded, saved, command, extend)
    if not found:
        return
    name, before, now = found[0]
    more = f" (and {', '.join(option(n) for n, _, _ in found[1:])})" if found[1:] else ""
    raise UsageError(f"--out {out} holds another run: {option(name)} is {shown(before)} there, {shown(now)} in this "
                     f"command{more}; expected the run's own options to resume it, or --fresh (its checkpoints and "
                     f"log are replaced) or another --out for a new run")


def option(name: str) -> str:
    return "--" + name.replace("_", "-")


def shown(value) -> str:
    return " ".join(map(str, value)) if isinstance(value, tuple) else repr(value)


# --- the demonstrations ----------------------------------------------------------------------------------------


def demo_digests(train: list[Path], val: list[Path]) -> dict:
    return {"train": demos_digest(train), "val": demos_digest(val) if val else None}


def check_same_demos(out: Path, digests: dict) -> None:
    """A rerun's demos must be the run's (OUT/demos.json); a run from before the file was kept is not checked."""
    path = out / DIGEST_NAME
    if not path.is_file():
        return
    try:
        recorded = json.loads(path.read_text())
    except (OSError, ValueError):
        return
    for split, value in digests.items():
        if recorded.get(split, value) != value:
            raise UsageError(f"--data.{split}: these demonstrations differ from those the run in {out} was trained "
                             f"on ({path} records their digest); expected the same files to resume it, or --fresh "
                             f"or another --out for a new run")


def keep_digests(out: Path, digests: dict) -> None:
    write_text(out / DIGEST_NAME, json.dumps(digests, indent=1) + "\n")


RUN_FILES = ("last", ".last.old", "best", ".best.old", "steps", "log.jsonl", "summary.json", DIGEST_NAME)
"""what a run writes into OUT beside config.json: --fresh removes them before it starts"""


def clear_run(out: Path) -> None:
    for name in RUN_FILES:
        path = out / name
        if path.is_dir():
            shutil.rmtree(path)
        elif path.exists():
            path.unlink()
