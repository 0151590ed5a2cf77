"""Every option of every command is described once in its --help, with its default shown once."""

from __future__ import annotations

import dataclasses
import importlib

import pytest

from tax3d.cli import COMMANDS, main
from tax3d.config import field_docs

def options_of(cls, prefix=""):
    """(option name, its docstring) of every field of an Args class, nested sections included."""
    docs = field_docs(cls)
    for f in dataclasses.fields(cls):
        if dataclasses.is_dataclass(f.type) or (isinstance(f.type, str) and f.type.endswith("Overrides")):
            continue
        yield prefix + f.name, docs.get(f.name, "")


@pytest.mark.parametrize("name", list(COMMANDS))
def test_every_option_is_described(name):
    module = importlib.import_module(COMMANDS[name][0])
    undescribed = [option for option, doc in options_of(module.Args) if not doc]
    assert not undescribed, f"tax3d {name}: {undescribed}"


def test_every_option_of_train_dp3_is_described():
    from tax3d.baselines.dp3 import config as dp3

    for section in (dp3.ModelConfig, dp3.DiffusionConfig, dp3.DataConfig, dp3.TrainConfig):
        assert set(field_docs(section)) == {f.name for f in dataclasses.fields(section)}, section


@pytest.mark.parametrize("name", list(COMMANDS))
def test_a_default_the_description_gives_is_not_shown_again(name, capsys):
    import re

    with pytest.raises(SystemExit):
        main([name, "--help"])
    text = " ".join(capsys.readouterr().out.replace("│", " ").split())
    twice = [chunk for chunk in re.split(r" (?=--[a-z])", text) if chunk.count("default:") > 1]
    assert not twice, twice


def test_train_dp3_takes_the_preset_that_fits_the_machine(monkeypatch, capsys):
    import torch

    from tax3d.cli import train_dp3 as dp3_train

    for cuda, preset in ((False, "cpu"), (True, "paper")):
        monkeypatch.setattr(torch.cuda, "is_available", lambda: cuda)
        assert dp3_train.default_preset(None) == preset
        assert f"--preset not given: using {preset}" in capsys.readouterr().err
    assert dp3_train.Args().preset is None


def test_demo_without_the_shipped_checkpoints_says_where_they_are(monkeypatch, capsys, tmp_path):
    from tax3d.cli import demo

    monkeypatch.setattr(demo, "SHIPPED", tmp_path / "site-packages" / "checkpoints" / "tax3d-cd-simple")
    args = demo.Args(checkpoint=demo.SHIPPED, out=tmp_path / "out")
    from tax3d.errors import UsageError

    with pytest.raises(UsageError, match="the shipped checkpoints are in the repository's checkpoints/ folder"):
        demo.run(args)
