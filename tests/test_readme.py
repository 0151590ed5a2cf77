"""The README's command block runs as written, in order, in a fresh folder: only the sizes are made tiny.

Each `tax3d` call of the block goes through a shell function that appends options for a tiny run (one episode, a
few steps, a small network); options given later win, so the README's own options are all exercised."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

TINY = {
    "generate": "--num 1 --workers 1",
    "train": "--train.steps 2 --train.val-every 2 --train.val-demos 1 --model.hidden-size 16 --model.depth 1 "
             "--data.num-action-points 32 --data.num-anchor-points 32 --train.num-workers 0",
    "predict": "--steps 2",
    "eval": "--episodes 1 --workers 1 --steps 2 --no-report",
    "table": "--num-train 1 --num-val 1 --episodes 1 --steps 2 --workers 1",
    "train-dp3": "--train.steps 2 --train.batch-size 2",
}


def readme_block() -> str:
    text = (ROOT / "README.md").read_text()
    match = re.search(r"## Commands\n\n```bash\n(.*?)```", text, re.S)
    assert match, "README.md has no ## Commands bash block"
    return match.group(1)


def test_every_command_of_the_block_has_a_tiny_size():
    commands = set(re.findall(r"\btax3d ([a-z0-9-]+)", readme_block()))
    assert commands and commands <= set(TINY), commands - set(TINY)
    assert "generate" in commands and "train" in commands and "eval" in commands


def run_tiny(block: str, folder: Path, timeout: int, train_extra: str = "") -> subprocess.CompletedProcess:
    """A bash block run in `folder` with each `tax3d` call given its tiny options (and `train_extra` on train)."""
    cases = "\n".join(f"        {name}) extra='{options}' ;;" for name, options in TINY.items())
    extra = f'    if [ "$1" = train ]; then extra="$extra {train_extra}"; fi\n' if train_extra else ""
    script = f"""set -euo pipefail
tax3d() {{
    local extra=""
    case "$1" in
{cases}
    esac
{extra}    command tax3d "$@" $extra
}}
{block}"""
    bin_dir = Path(sys.executable).parent
    env = {**os.environ, "PATH": f"{bin_dir}{os.pathsep}{os.environ['PATH']}", "OMP_NUM_THREADS": "1"}
    done = subprocess.run(["bash", "-c", script], cwd=folder, env=env, capture_output=True, text=True,
                          timeout=timeout)
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    return done


def statements(block: str) -> list[str]:
    """The block's statements in order: lines joined across a trailing backslash, a for loop whole."""
    out, current = [], ""
    for line in block.splitlines():
        current += line + "\n"
        if line.endswith("\\") or (current.lstrip().startswith("for ") and line.strip() != "done"):
            continue
        if current.strip():
            out.append(current)
        current = ""
    return out


# The block in three parts that need nothing of each other (each runs in a folder of its own, the parts side by
# side under `make test`): each statement goes to the part of the first command it names.
PARTS = {
    "model": ("generate --task hangproccloth-simple --split $split", "train ", "predict", "eval"),
    "table": ("table",),
    "dp3": ("--trajectories", "train-dp3"),
}
CHECKS = {
    "model": "test -f runs/cd/pred.json && test -d runs/cd/best && test -f out/eval/results.json\n",
    "table": "test -f runs/table/results.md\n",
    "dp3": "test -d runs/dp3/last\n",
}


def part_of(statement: str) -> str:
    """The part whose key the statement names (a key starting with -- names an option; "model" where none)."""
    for name, keys in reversed(PARTS.items()):
        if any((key if key.startswith("--") else f"tax3d {key}") in statement for key in keys):
            return name
    return "model"


def test_the_parts_are_the_whole_block_in_its_order():
    block = readme_block()
    assert "".join(statements(block)) == "".join(line + "\n" for line in block.splitlines() if line.strip())
    parts = [part_of(s) for s in statements(block)]
    assert set(parts) == set(PARTS)
    assert parts == sorted(parts, key=list(PARTS).index), parts  # a part's statements follow those it needs


@pytest.mark.slow
@pytest.mark.parametrize("part", PARTS)
def test_readme_commands_run_as_written(tmp_path, part):
    block = "".join(s for s in statements(readme_block().replace(". .venv/bin/activate\n", "")) if part_of(s) == part)
    run_tiny(block + CHECKS[part], tmp_path, 900)
