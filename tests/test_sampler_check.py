"""scripts/sampler_check.py: one checkpoint's goal RMSE under the three samplers, kept as JSON."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest

from tax3d import config as cfg
from tax3d.model.tax3d import Tax3D

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "scripts"))
import sampler_check  # noqa: E402

from tests.conftest import write_demos  # noqa: E402


def test_rows_per_checkpoint_and_sampler(tmp_path):
    write_demos(tmp_path / "demos", 3)
    config = cfg.validate(cfg.Config(
        model=cfg.ModelConfig(variant="cd", hidden_size=16, depth=1, num_heads=2),
        data=cfg.DataConfig(num_action_points=16, num_anchor_points=16),
    ))
    Tax3D(config).save_pretrained(tmp_path / "ckpt")
    out = tmp_path / "kept" / "samplers.json"
    assert sampler_check.main(["--checkpoints", str(tmp_path / "ckpt"), "--demos", str(tmp_path / "demos"),
                               "--first", "2", "--out", str(out)]) == 0
    kept = json.loads(out.read_text())
    assert kept["demos"] == 2 and kept["samples"] == 2 and "--first 2" in kept["command"]
    (row,) = kept["rows"]
    assert row["variant"] == "cd"
    values = [row["ddpm_10"], row["ddim_10"], row["ddpm_100"]]
    assert all(v > 0 for v in values) and len(set(values)) == 3


@pytest.mark.parametrize("bad", ["--checkpoints", "--demos"])
def test_a_missing_path_is_a_one_line_error(tmp_path, capsys, bad):
    write_demos(tmp_path / "demos", 1)
    args = {"--checkpoints": str(tmp_path / "ckpt"), "--demos": str(tmp_path / "demos")}
    if bad == "--demos":
        Tax3D(cfg.validate(cfg.Config(model=cfg.ModelConfig(hidden_size=16, depth=1, num_heads=2)))).save_pretrained(
            tmp_path / "ckpt")
        args["--demos"] = str(tmp_path / "absent")
    assert sampler_check.main([w for k, v in args.items() for w in (k, v)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and ("absent" if bad == "--demos" else "ckpt") in err
