"""docs/own-data.md runs as written, in a fresh folder: its command block (only the sizes made tiny), then its
Python snippet on the checkpoint the block trained."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from tests.test_readme import run_tiny

ROOT = Path(__file__).resolve().parents[1]
PAGE = ROOT / "docs" / "own-data.md"


def blocks(language: str) -> list[str]:
    return re.findall(rf"```{language}\n(.*?)```", PAGE.read_text(), re.S)


def test_the_page_is_linked_from_the_readme_and_its_commands_have_tiny_sizes():
    assert "(docs/own-data.md)" in (ROOT / "README.md").read_text()
    (block,) = blocks("bash")
    assert {"train", "predict"} == set(re.findall(r"\btax3d ([a-z0-9-]+)", block)) and "write_demo" in block


@pytest.mark.slow
def test_the_page_runs_as_written(tmp_path):
    (block,) = blocks("bash")
    (snippet,) = [b for b in blocks("python") if "Tax3D" in b]
    checks = f"""
test -f runs/mine/pred.json && test -d runs/mine/best && test -d runs/mine/last
python - <<'EOF'
{snippet}
assert goals.shape == (5, 300, 3), goals.shape
import json, numpy as np
assert json.load(open("runs/mine/best/config.json"))["data"]["task"] == "custom"
assert np.load("runs/mine/pred.npz")["goals"].shape == (2, 5, 300, 3)
EOF
"""
    done = run_tiny(block + checks, tmp_path, 600, train_extra="--train.minutes 0")
    assert "predictions: runs/mine/pred.npz" in done.stderr


def test_the_camera_snippet_runs_as_written():
    (snippet,) = [b for b in blocks("python") if "depth_to_cloud" in b]
    scope: dict = {}
    exec(compile(snippet, str(PAGE), "exec"), scope)
    cloth = scope["cloth"]
    assert cloth.shape == (80 * 80, 3) and abs(cloth[:, 2] - 0.8).max() < 1e-12  # 800 mm deep, in metres
