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


@pytest.mark.parametrize("section,name,neutral,other", [("model", "mean_input", False, True),
                                                        ("data", "target_scale", 1.0, 0.4)])
def test_a_retired_option_loads_at_its_neutral_value_and_is_an_error_at_another(section, name, neutral, other):
    assert cfg.from_dict(old_config(section, **{name: neutral})) == cfg.cpu()
    with pytest.raises(UsageError) as err:
        cfg.from_dict(old_config(section, **{name: other}), "old/config.json")
    message = str(err.value)
    assert len(message.splitlines()) == 1 and f"{section}.{name}" in message and "retired" in message
    assert message.startswith("old/config.json: ")


@pytest.mark.parametrize("loss", ["min_snr", "v_capped"])
def test_a_retired_loss_is_an_error_naming_it(loss):
    with pytest.raises(UsageError, match=f"diffusion.loss is '{loss}': that loss was retired; expected one of "
                                         "'epsilon', 'x0', 'v'"):
        cfg.from_dict(old_config("diffusion", loss=loss))


def test_every_shipped_checkpoint_config_loads():
    from pathlib import Path

    for path in sorted((Path(__file__).resolve().parents[1] / "checkpoints").glob("*/config.json")):
        cfg.load(path)


def test_the_preset_option_names_every_preset():
    import typing

    assert typing.get_args(cfg.PresetName) == tuple(cfg.PRESETS)
