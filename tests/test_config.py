"""config.json of earlier versions: retired fields load at their neutral value and are a one-line error otherwise."""

from __future__ import annotations

import pytest

from tax3d import config as cfg
from tax3d.errors import UsageError


def old_config(section: str, **fields) -> dict:
    data = cfg.to_dict(cfg.cpu())
    data[section].update(fields)
    return data


def test_the_knee_of_a_replanned_run_loads_at_any_value_and_is_dropped():
    """Earlier versions kept a re-planned --train.minutes run's knee in config.json; it is run state, now in the
    training state."""
    config = cfg.from_dict(old_config("train", replan_step=3299, replan_progress=0.16))
    assert config == cfg.cpu() and "replan_step" not in cfg.to_dict(config)["train"]
