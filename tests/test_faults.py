"""Faults partway through a command: the output folder deleted under a running train, a full disk. Each ends the
command within seconds, in one line and a non-zero code, with no process of it left behind."""

from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from tests.conftest import TINY, write_demos

ROOT = Path(__file__).resolve().parents[1]


def children(pid: int) -> list[int]:
    """The processes whose parent is pid (from /proc)."""
    found = []
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                fields = (entry / "stat").read_text().rsplit(")", 1)[1].split()
            except OSError:
                continue
            if int(fields[1]) == pid:
                found.append(int(entry.name))
    return found


def running(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state != "Z"


def start_train(out: Path, data: Path, *extra: str) -> subprocess.Popen:
    env = {**os.environ, "PYTHONPATH": str(ROOT / "src")}
    return subprocess.Popen([sys.executable, "-m", "tax3d.cli", "train", *TINY, "--train.num_workers", "1",
                             "--train.steps", "100000", "--train.val_every", "5", "--data.train", str(data),
                             "--out", str(out), *extra], env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)


def said(err: str) -> list[str]:
    """The lines of stderr but the progress bar's."""
    return [line for line in err.splitlines() if line.strip() and not line.startswith("train:")]


def wait_for(test, seconds: float) -> bool:
    end = time.time() + seconds
    while time.time() < end:
        if test():
            return True
        time.sleep(0.1)
    return False


def finish(process: subprocess.Popen, seconds: float) -> tuple[int | None, str]:
    """The exit code within `seconds` (None: still running, then killed with its children) and stderr."""
    try:
        _, err = process.communicate(timeout=seconds)
        return process.returncode, err
    except subprocess.TimeoutExpired:
        for pid in children(process.pid):
            os.kill(pid, signal.SIGKILL)
        process.kill()
        return None, process.communicate()[1]


def test_deleting_the_output_folder_under_a_running_train_ends_it(tmp_path):
    import shutil

    data = tmp_path / "demos"
    write_demos(data, 2)
    out = tmp_path / "run"
    process = start_train(out, data)
    assert wait_for(lambda: (out / "last").is_dir(), 120), finish(process, 1)[1]
    workers = children(process.pid)
    assert workers, "expected a data worker"
    shutil.rmtree(out)
    code, err = finish(process, 30)
    assert code == 1, err
    lines = said(err)
    assert len(lines) == 1 and lines[0].startswith("tax3d train: error: no such file or directory writing "), err
    assert str(out) in lines[0]
    assert not [pid for pid in workers if running(pid)], "a data worker outlived the run"


@pytest.fixture
def small_disk(tmp_path):
    """A 2 MB filesystem (tmpfs), where this process may mount one; skipped elsewhere."""
    folder = tmp_path / "small"
    folder.mkdir()
    if os.geteuid() != 0 or subprocess.run(["mount", "-t", "tmpfs", "-o", "size=2M", "tmpfs", str(folder)],
                                           capture_output=True).returncode != 0:
        pytest.skip("cannot mount a small filesystem here")
    yield folder
    subprocess.run(["umount", "-l", str(folder)], check=True)


def test_a_full_disk_is_one_sentence_and_keeps_the_last_checkpoint(tmp_path, small_disk):
    import torch

    from tax3d.model.tax3d import Tax3D

    data = tmp_path / "demos"
    write_demos(data, 2)
    out = small_disk / "run"
    process = start_train(out, data, "--train.keep_every", "5")  # a checkpoint kept at every validation fills it
    code, err = finish(process, 300)
    assert code == 1, err
    lines = said(err)
    assert len(lines) == 1 and lines[0].startswith(f"tax3d train: error: no space left on device writing {out}/")
    state = torch.load(out / "last" / "training_state.pt", weights_only=True)
    assert state["step"] >= 5 and Tax3D.from_pretrained(out / "last") is not None
    leftovers = [p.name for p in out.rglob("*") if p.name.startswith(".") or p.suffix == ".tmp"]
    assert not leftovers, leftovers


@pytest.fixture
def full_disk(small_disk):
    """The small filesystem filled to its last few kilobytes: the first demo or episode written fails."""
    free = os.statvfs(small_disk)
    (small_disk / "filler").write_bytes(bytes(free.f_bavail * free.f_frsize - 4096))
    return small_disk


@pytest.mark.parametrize("command", ["generate", "eval"])
def test_a_full_disk_ends_generate_and_eval_in_one_sentence(full_disk, command):
    out = full_disk / "out"
    args = {"generate": ["--task", "hangproccloth-simple", "--split", "train", "--num", "2"],
            "eval": ["--checkpoint", str(ROOT / "checkpoints" / "tax3d-cd-simple"), "--splits", "unseen",
                     "--episodes", "2"]}[command]
    env = {**os.environ, "PYTHONPATH": str(ROOT / "src")}
    process = subprocess.Popen([sys.executable, "-m", "tax3d.cli", command, *args, "--workers", "1", "--out", str(out)],
                               env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    code, err = finish(process, 120)
    assert code == 1, err
    lines = [line for line in re.sub(r"episodes:[^\]]*\]", "", err).splitlines() if line.strip()]  # less the bar
    assert len(lines) == 1 and lines[0].startswith(f"tax3d {command}: error: no space left on device writing {out}/"), err
    assert not [p.name for p in out.rglob("*") if p.is_file()], "a half-written file was left"
