"""Backends for episodes: in-process, local process pool and Ray give the same results; errors come back per job."""

import importlib.util
import math
import os

import numpy as np
import pytest

from tax3d.cli import main
from tax3d.errors import UsageError
from tax3d.parallel import check_backend, run_each

HAS_RAY = importlib.util.find_spec("ray") is not None


def collect(backend, workers, jobs):
    out = {}
    for i, result, error in run_each(math.sqrt, jobs, workers, backend):
        out[i] = ("error", type(error).__name__) if error is not None else result
    return out


def test_local_backends_agree_and_keep_errors_per_job():
    jobs = [4.0, -1.0, 9.0]
    inline, pool = collect("local", 1, jobs), collect("local", 2, jobs)
    assert inline == pool
    assert inline[0] == 2.0 and inline[2] == 3.0 and inline[1] == ("error", "ValueError")


def pid(_job) -> int:
    return os.getpid()


@pytest.mark.parametrize("workers", [1, 2])
def test_fresh_runs_every_job_in_a_process_of_its_own(workers):
    """What a PyBullet process simulated before must not reach the next job: generation asks for `fresh`."""
    pids = [p for _, p, error in run_each(pid, range(4), workers, fresh=True) if error is None]
    assert len(pids) == 4 and len(set(pids)) == 4 and os.getpid() not in pids
    assert {p for _, p, _ in run_each(pid, range(4), 1)} == {os.getpid()}  # without it, one worker runs inline


def test_bad_backend_options():
    with pytest.raises(UsageError, match="--backend 'spark'"):
        check_backend("spark", 1, None)
    with pytest.raises(UsageError, match="--address"):
        check_backend("local", 1, "10.0.0.1:6379")
    with pytest.raises(UsageError, match="--workers 0"):
        check_backend("local", 0, None)


def test_generate_rejects_a_bad_backend_in_one_line(capsys, tmp_path):
    assert main(["generate", "--backend", "local", "--address", "x:1", "--out", str(tmp_path / "d")]) == 2
    err = capsys.readouterr().err.strip()
    assert "--address" in err and len(err.splitlines()) == 1


@pytest.mark.skipif(not HAS_RAY, reason="Ray is an optional extra")
def test_ray_backend_matches_local_and_keeps_errors():
    jobs = [4.0, -1.0, 16.0]
    assert collect("ray", 2, jobs) == collect("local", 1, jobs)


@pytest.mark.slow
@pytest.mark.skipif(not HAS_RAY, reason="Ray is an optional extra")
def test_ray_generates_the_same_demos_as_the_local_backend(tmp_path):
    from tax3d.data.format import list_demos, load_demo

    common = ["generate", "--task", "hangproccloth-simple", "--split", "train", "--num", "2"]
    assert main(common + ["--out", str(tmp_path / "local"), "--workers", "1"]) == 0
    assert main(common + ["--out", str(tmp_path / "ray"), "--workers", "2", "--backend", "ray"]) == 0
    local, ray = list_demos(tmp_path / "local"), list_demos(tmp_path / "ray")
    assert [p.name for p in local] == [p.name for p in ray] and len(local) == 2
    for a_path, b_path in zip(local, ray):
        a, b = load_demo(a_path), load_demo(b_path)
        assert a["deform_params"] == b["deform_params"]
        for key in ("action_pc", "anchor_pc", "flow", "rot", "trans"):
            np.testing.assert_array_equal(a[key], b[key])


def sleep_then_write(job):
    """A job: sleep, then write a file (as a demonstration would be written)."""
    import time
    from pathlib import Path

    seconds, path = job
    time.sleep(seconds)
    Path(path).write_text("done")
    return path


def test_an_interrupt_stops_the_pool_at_once(tmp_path):
    """Ctrl-C (a KeyboardInterrupt in the loop) ends the workers within seconds: no job runs or writes after it."""
    import time

    jobs = [(0.0, tmp_path / "first")] + [(3.0, tmp_path / f"late_{i}") for i in range(6)]
    steps = run_each(sleep_then_write, jobs, workers=2)
    next(steps)
    started = time.time()
    with pytest.raises(KeyboardInterrupt):
        steps.throw(KeyboardInterrupt)
    assert time.time() - started < 2.0
    time.sleep(3.5)  # long enough for a surviving worker to finish its job and write
    assert sorted(p.name for p in tmp_path.iterdir()) == ["first"]
