"""One run, one folder: a lock on --out, and a rerun into a run's folder resumes that run only."""

from __future__ import annotations

import json
import subprocess
import sys

from tax3d.training import runlock
from tax3d.cli import main

from tests.conftest import TINY, read_log, write_demos
from tests.test_faults import finish, start_train, wait_for

SHORT = [*TINY, "--train.steps", "4", "--train.val_every", "2"]


def one_line(capsys, argv: list[str], code: int) -> str:
    assert main(argv) == code
    err = [line for line in capsys.readouterr().err.splitlines() if line.strip() and not line.startswith("train:")]
    assert len(err) == 1, err
    return err[0]


def test_a_second_run_into_a_folder_in_use_is_refused(tmp_path, capsys):
    data = tmp_path / "demos"
    write_demos(data, 2)
    out = tmp_path / "run"
    first = start_train(out, data)
    try:
        assert wait_for(lambda: (out / "log.jsonl").is_file(), 120)
        line = one_line(capsys, ["train", *SHORT, "--data.train", str(data), "--out", str(out)], 2)
        assert f"--out {out}: another run (process {first.pid}) is writing there" in line
    finally:
        first.terminate()
        finish(first, 60)
    assert (out / "last").is_dir() and not (out / runlock.LOCK_NAME).exists()


def test_a_stale_lock_is_taken_over_and_said(tmp_path, capsys):
    data = tmp_path / "demos"
    write_demos(data, 2)
    out = tmp_path / "run"
    out.mkdir()
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    (out / runlock.LOCK_NAME).write_text(f"{dead.pid}\n")  # the file a killed run leaves: no process holds it
    assert main(["train", *SHORT, "--data.train", str(data), "--out", str(out)]) == 0
    assert f"taking over the lock left by process {dead.pid}, which is no longer running" in capsys.readouterr().err
    assert not (out / runlock.LOCK_NAME).exists()


def test_bad_input_leaves_no_folder_behind(tmp_path, capsys):
    out = tmp_path / "new"
    one_line(capsys, ["train", *SHORT, "--data.train", str(tmp_path / "none"), "--out", str(out)], 2)
    assert not out.exists()


def test_a_rerun_resumes_only_the_same_run(tmp_path, capsys):
    data, other = tmp_path / "demos", tmp_path / "other"
    write_demos(data, 2)
    write_demos(other, 2, seed=5)
    out = tmp_path / "run"
    command = ["train", *SHORT, "--data.train", str(data), "--out", str(out)]
    assert main(command) == 0
    kept = {name: (out / name).read_bytes() for name in ("config.json", "summary.json", "log.jsonl")}
    capsys.readouterr()
    refused = [
        (["--data.train", str(other)], f"--out {out} holds another run: --data.train is {data} there, {other} in "
                                       f"this command"),
        (["--preset", "cpu-fast"], "--data.predict-points is None there, 256 in this command (and --train.val-points)"),
        (["--train.minutes", "5"], "--train.minutes is 0.0 there, 5.0 in this command"),
        (["--model.variant", "cp"], "--model.variant is 'cd' there, 'cp' in this command"),
    ]
    for extra, message in refused:
        line = one_line(capsys, [*command, *extra], 2)
        assert message in line and "--fresh" in line, line
    # the same folder of demos with other contents
    for path in sorted(data.iterdir()):
        path.unlink()
    write_demos(data, 2, seed=9)
    line = one_line(capsys, command, 2)
    assert line.startswith("tax3d train: error: --data.train: these demonstrations differ from those the run in")
    assert {name: (out / name).read_bytes() for name in kept} == kept  # nothing rewritten
    # --fresh starts another run in the folder
    assert main([*command, "--fresh"]) == 0
    assert "resuming" not in capsys.readouterr().err and [r["step"] for r in read_log(out)] == [1, 2, 3, 4]


def test_the_same_command_resumes_and_options_of_how_may_change(tmp_path, capsys):
    data = tmp_path / "demos"
    write_demos(data, 2)
    out = tmp_path / "run"
    command = ["train", *TINY, "--train.steps", "4", "--train.val_every", "2", "--data.train", str(data),
               "--out", str(out)]
    assert main(command) == 0
    capsys.readouterr()
    assert main([*command, "--train.threads", "2", "--train.num_workers", "1"]) == 0
    assert f"resuming {out} at step 4" in capsys.readouterr().err
    # --train.steps moves the run's end only with --resume, which asks to continue that run
    assert main([*command, "--train.steps", "6"]) == 2 and "--train.steps is 4 there" in capsys.readouterr().err
    assert main([*command, "--train.steps", "6", "--resume"]) == 0
    assert [r["step"] for r in read_log(out)] == [1, 2, 3, 4, 5, 6]


def test_a_run_folder_from_before_the_digest_and_newer_fields_resumes(tmp_path, capsys):
    """A run written before OUT/demos.json was kept, whose config.json lacks fields added since, resumes."""
    data = tmp_path / "demos"
    write_demos(data, 2)
    out = tmp_path / "run"
    command = ["train", *SHORT, "--data.train", str(data), "--out", str(out)]
    assert main(command) == 0
    (out / "demos.json").unlink()
    for path in (out / "config.json", out / "last" / "config.json"):
        config = json.loads(path.read_text())
        for section, name in (("train", "keep_every"), ("train", "val_points"), ("data", "rotate_scene")):
            del config[section][name]
        path.write_text(json.dumps(config))
    capsys.readouterr()
    assert main(command) == 0
    assert f"resuming {out} at step 4" in capsys.readouterr().err and (out / "demos.json").is_file()
