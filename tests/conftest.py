"""Shared fixtures and the helpers the test modules build their inputs with: tiny models, synthetic scenes and
demonstrations, the tiny training flags."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch

OFFICIAL = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "tax3d-official" / "hangproccloth-simple"
N, M = 24, 40  # action and anchor points of the synthetic scenes

# `tax3d train` flags for a run of seconds
TINY = ["--preset", "cpu", "--model.hidden_size", "32", "--model.depth", "2", "--model.num_heads", "2",
        "--data.num_action_points", "16", "--data.num_anchor_points", "24", "--data.train_size", "16",
        "--train.batch_size", "8", "--train.threads", "1", "--train.num_workers", "0",
        "--train.val_samples", "2", "--train.val_demos", "0"]


def tiny_config(variant: str = "cd", **data):
    from tax3d import config as cfg

    config = cfg.Config(
        model=cfg.ModelConfig(variant=variant, hidden_size=16, depth=1, num_heads=2),
        diffusion=cfg.DiffusionConfig(num_timesteps=100, sample_steps=5),
        data=cfg.DataConfig(**{"num_action_points": 32, "num_anchor_points": 24, **data}),
    )
    return cfg.validate(config)


def tiny_model(variant: str = "cd", seed: int = 0, **data):
    """A tiny model with every weight random: zero-initialised layers would hide what the inputs do."""
    from tax3d.model.tax3d import Tax3D

    torch.manual_seed(seed)
    model = Tax3D(tiny_config(variant, **data))
    with torch.no_grad():
        for p in model.parameters():
            p.normal_(0.0, 0.1)
    return model.eval()


def scene(seed: int | np.random.Generator = 0, n: int = N, m: int = M):
    """A cloth-like action cloud, a hanger-like anchor far from the origin, and a goal near the anchor."""
    rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
    action = rng.normal(size=(n, 3)) * [2.0, 0.1, 2.0] + [0.0, 5.0, 8.0]
    anchor = rng.normal(size=(m, 3)) * [0.5, 0.5, 2.0] + [4.0, -6.0, 3.0]
    goal = rng.normal(size=(n, 3)) * [2.0, 0.5, 1.0] + [4.5, -6.5, 8.0]
    return action, anchor, goal


def synthetic_demo(seed: int | np.random.Generator = 0, n: int = N, m: int = M) -> dict:
    """A demonstration in the official layout around `scene`."""
    action, anchor, goal = scene(seed, n, m)
    return {
        "action_pc": action, "action_seg": np.ones(n), "anchor_pc": anchor,
        "anchor_seg": np.zeros(m, dtype=np.int32), "flow": goal - action, "speed_factor": np.array(1.0),
        "rot": np.zeros(3), "trans": np.zeros(3),
        "deform_params": {"num_holes": 1, "node_density": 25, "w": 1.0, "h": 1.0,
                          "holes": [{"x0": 8, "x1": 16, "y0": 9, "y1": 13}]},
        "anchors": {0: {"pos": np.zeros(3), "vertices": [0]}},
    }


def write_demos(folder: Path, count: int, seed: int = 0, n: int = 40, m: int = 60) -> list[dict]:
    """`count` synthetic demonstrations drawn from one generator, saved as demo_0.npz, demo_1.npz, ..."""
    from tax3d.data.format import save_demo

    folder.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(seed)
    demos = [synthetic_demo(rng, n, m) for _ in range(count)]
    for i, demo in enumerate(demos):
        save_demo(folder / f"demo_{i}.npz", demo)
    return demos


def make_demo(n: int = 10, m: int = 20, seed: int = 0) -> dict:
    """A demonstration of random points with the fixed cloth's parameters (for format round trips)."""
    from tax3d.sim.cloth import SIMPLE_CLOTH

    rng = np.random.default_rng(seed)
    return {
        "action_pc": rng.normal(size=(n, 3)),
        "action_seg": np.ones(n),
        "anchor_pc": rng.normal(size=(m, 3)),
        "anchor_seg": np.zeros(m, dtype=np.int32),
        "flow": rng.normal(size=(n, 3)),
        "speed_factor": np.array(1.0),
        "rot": np.array([0.0, 0.0, 0.3]),
        "trans": np.array([1.0, -2.0, 0.0]),
        "deform_params": dict(SIMPLE_CLOTH),
        "anchors": {3: {"pos": np.array([3.0, 5.0, 11.0]), "vertices": [n - 1]}},
    }


def one_line_error(capsys, argv, *expected, main=None) -> str:
    """Run `main` (tax3d's CLI where None) on argv; it must exit 2 with one line on stderr (no traceback) holding
    every expected text."""
    if main is None:
        from tax3d.cli import main

    code = main(list(map(str, argv)))
    err = "\n".join(line for line in capsys.readouterr().err.replace("\r", "\n").splitlines()
                    if line.strip() and "it/s]" not in line)  # progress bars aside
    assert code == 2, err
    assert len(err.splitlines()) == 1 and "Traceback" not in err, err
    for text in expected:
        assert text in err, err
    return err


def read_log(out: Path) -> list[dict]:
    """The records of a run's log.jsonl."""
    from tax3d.checkpoint import read_log as read_records

    return read_records(out / "log.jsonl")


@pytest.fixture(scope="session")
def official_dir() -> Path:
    if not OFFICIAL.is_dir():
        pytest.skip(f"official demonstrations not found at {OFFICIAL}")
    return OFFICIAL


@pytest.fixture(scope="session")
def generated(tmp_path_factory):
    """One real, full-length expert episode of HangProcCloth-simple (about 10 s), shared by the tests that need one."""
    from tax3d.sim.generate import Args, generate

    out = tmp_path_factory.mktemp("demos")
    stats = generate(Args(task="hangproccloth-simple", split="unseen", num=1, out=out), progress=False)
    return out, stats


@pytest.fixture
def demos(tmp_path):
    """Two small synthetic demonstrations in a folder."""
    from tax3d.data.format import save_demo

    folder = tmp_path / "demos"
    folder.mkdir()
    for i in range(2):
        save_demo(folder / f"demo_{i}.npz", synthetic_demo(i))
    return folder


@pytest.fixture(autouse=True)
def own_ledger(tmp_path_factory, monkeypatch):
    """Each test's scorings of test episodes go to a ledger of its own, never to the repository's (tax3d.eval.ledger);
    the variable reaches the commands a test runs in a process of their own too."""
    path = tmp_path_factory.mktemp("ledger") / "ledger.jsonl"
    monkeypatch.setenv("TAX3D_LEDGER", str(path))
    return path
