"""Every shipped checkpoint loads, its weights match the recorded sha256, and it predicts its kept golden goal.

The scene is fixed and needs no data: the HangProcCloth-simple cloth (580 vertices) where the scene loads it, and
points drawn with a fixed seed on the hanger's and the rod's cylinders. Each checkpoint predicts one sample with
seed 0 in GOLDEN_STEPS steps of its own sampler; tests/golden/<checkpoint>.npy keeps that goal (float32).

When a change is meant to change the predictions (or a checkpoint is added or retrained), write the goldens again:

    PYTHONPATH=src python -m tests.test_checkpoints --write
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

ROOT = Path(__file__).resolve().parents[1]
CHECKPOINTS = sorted(p for p in (ROOT / "checkpoints").iterdir() if (p / "config.json").is_file())
GOLDEN = Path(__file__).resolve().parent / "golden"
GOLDEN_STEPS = 10
SEED = 0
ANCHOR_POINTS_PER_PART = 60


def fixed_scene() -> tuple[np.ndarray, np.ndarray]:
    """World-frame action (580, 3) and anchor (300, 3) points of the HangProcCloth scene, anchor at the origin."""
    from tax3d.sim import anchor, env
    from tax3d.sim.cloth import SIMPLE_CLOTH, build_cloth

    turn = Rotation.from_euler("xyz", env.CLOTH_EULER).as_matrix()
    action = build_cloth(SIMPLE_CLOTH).local * env.CLOTH_SCALE @ turn.T + env.CLOTH_POSITION
    rng = np.random.default_rng(SEED)
    parts = []
    for cylinders, base in ((anchor.HANGER_PARTS, anchor.HANGER_POSITION), (anchor.ROD_PARTS, np.zeros(3))):
        for radius, length, centre, degrees in cylinders:
            angle = rng.uniform(0.0, 2 * np.pi, ANCHOR_POINTS_PER_PART)
            height = rng.uniform(-0.5, 0.5, ANCHOR_POINTS_PER_PART) * length
            local = np.stack([radius * np.cos(angle), radius * np.sin(angle), height], axis=1)
            tilt = Rotation.from_euler("y", degrees, degrees=True).as_matrix()
            parts.append((local @ tilt.T + centre) * anchor.SCALE + base)
    return action, np.concatenate(parts)


def predict(directory: Path) -> np.ndarray:
    from tax3d.model.tax3d import Tax3D

    model = Tax3D.from_pretrained(directory)
    action, anchor_points = fixed_scene()
    steps = GOLDEN_STEPS if model.spec.diffusion else None
    return model.predict(action, anchor_points, num_samples=1, steps=steps, seed=SEED)[0].astype(np.float32)


def test_every_checkpoint_has_a_golden():
    assert len(CHECKPOINTS) == 9
    assert sorted(p.stem for p in GOLDEN.glob("*.npy")) == [p.name for p in CHECKPOINTS]


@pytest.mark.parametrize("directory", CHECKPOINTS, ids=lambda p: p.name)
def test_checkpoint_predicts_its_golden_goal(directory):
    from tax3d.baselines.dp3 import is_dp3_checkpoint
    from tax3d.checkpoint import CONFIG_NAME, WEIGHTS_NAME, sha256

    assert not is_dp3_checkpoint(directory), "a DP3 checkpoint needs its own prediction here"
    recorded = json.loads((directory / CONFIG_NAME).read_text()).get("weights_sha256")
    if recorded is not None:
        assert sha256(directory / WEIGHTS_NAME) == recorded, f"{directory.name}: weights differ from {CONFIG_NAME}"
    golden = GOLDEN / f"{directory.name}.npy"
    assert golden.is_file(), f"no golden for {directory.name}: python -m tests.test_checkpoints --write"
    np.testing.assert_allclose(predict(directory), np.load(golden), rtol=0, atol=1e-4)


def write_goldens() -> None:
    GOLDEN.mkdir(exist_ok=True)
    for directory in CHECKPOINTS:
        np.save(GOLDEN / f"{directory.name}.npy", predict(directory))
        print(f"wrote {GOLDEN / directory.name}.npy")


if __name__ == "__main__":
    if sys.argv[1:] != ["--write"]:
        sys.exit("usage: python -m tests.test_checkpoints --write")
    write_goldens()
