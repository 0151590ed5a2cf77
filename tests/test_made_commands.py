"""The training command beside a shipped checkpoint (on its result page and in its model card, a `tax3d train` or the
`tax3d table` of a table row) makes that checkpoint's configuration with today's presets: a preset that changed since
would otherwise make another model."""

from __future__ import annotations

import dataclasses
import json
import re
import shlex
import tomllib
from pathlib import Path

import pytest
import tyro

from tax3d import config as cfg
from tax3d.cli import table
from lab.results.commands import parses
from tax3d.cli.train import config_of_command, resolve_config

ROOT = Path(__file__).resolve().parents[1]
# train fields that change the weights; `steps` too unless the run was planned in minutes
TRAIN_FIELDS = ("lr", "weight_decay", "warmup_steps", "batch_size", "grad_clip", "seed", "ema", "minutes",
                "precision")


TRAIN_COMMAND = re.compile(r"\S*tax3d(\.cli)? train ")


def kept_commands() -> list:
    """A case for every `tax3d train` command given beside a kept configuration: a result row's `made` with its
    `shipped` checkpoint or `config` JSON, a page source's `config` with the command of its summary (and the options
    it was resumed with), and the training command of each model card."""
    results = ROOT / "docs" / "results"
    found = []
    for page in sorted((results / "pages").glob("*.toml")):
        declared = tomllib.loads(page.read_text())
        for source in declared.get("source", []):
            if source.get("config"):
                run = json.loads((results / source["summary"]).read_text())
                # today_options: what today's preset needs beside the recorded command to make the same configuration
                command = " ".join([run.get("command", ""), run.get("resumed_with", ""),
                                    source.get("today_options", "")])
                if TRAIN_COMMAND.match(command):
                    found.append(pytest.param(results / source["config"], command, id=f"{page.stem}:{source['id']}"))
        for row in declared.get("row", []):
            kept = (ROOT / row["shipped"] / "config.json") if row.get("shipped") else (
                results / row["config"] if row.get("config") else None)
            if kept is not None and TRAIN_COMMAND.match(row.get("made", "")):
                found.append(pytest.param(kept, row["made"], id=f"{page.stem}:{row['id']}"))
    for card in sorted((ROOT / "checkpoints").glob("*/README.md")):
        for line in card.read_text().splitlines():
            if line.startswith(("tax3d train", "tax3d table")):
                found.append(pytest.param(card.parent / "config.json", line, id=card.parent.name))
    return found


def made_config(command: str, kept: cfg.Config) -> cfg.Config:
    """The configuration `tax3d train ...` starts from, or the one `tax3d table ...` trains its row with (its
    training demonstrations read from KEPT: the table takes the first NUM of a folder that CI does not have)."""
    argv = shlex.split(command.split("#")[0])
    if "table" not in argv:
        return config_of_command(argv[argv.index("train") + 1:])
    args = tyro.cli(table.Args, args=argv[argv.index("table") + 1:], prog="tax3d table")
    data = args.data if args.data is not None else args.out / "data"
    (variant,) = args.variants.split(",")
    train_args = table.train_args(args, variant, Path("."), tuple(kept.data.train), data / "val")
    return resolve_config(train_args, Path("."), None)


def differences(made: cfg.Config, shipped: cfg.Config) -> list[str]:
    train = TRAIN_FIELDS + (() if shipped.train.minutes else ("steps",))
    out = []
    for section in ("model", "diffusion", "data", "train"):
        for f in dataclasses.fields(getattr(made, section)):
            a, b = getattr(getattr(made, section), f.name), getattr(getattr(shipped, section), f.name)
            if a != b and (section != "train" or f.name in train):
                out.append(f"{section}.{f.name}: {a!r} against {b!r}")
    return out


@pytest.mark.parametrize("kept,command", kept_commands())
def test_the_command_beside_a_kept_configuration_makes_it_with_todays_presets(kept, command):
    if kept.parent.parent != ROOT / "checkpoints" and not parses(command):
        pytest.skip("an option of the command was retired; its page shows it recorded with an earlier version")
    shipped = cfg.from_dict(json.loads(kept.read_text()), str(kept))
    assert not differences(made_config(command, shipped), shipped)

