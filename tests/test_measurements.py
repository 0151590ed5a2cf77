"""Measurements that `python -m lab.results` reads, each printed or written as kept JSON of its kind
(lab.results.kept): the studies lab.studies.mode_spread, success_by_rmse and the curves time_to_quality keeps, and
benchmarks/subnormal.py."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]


def study(name: str) -> list[str]:
    """The command line of a study of lab/studies, run from the repository's root."""
    return [sys.executable, "-m", f"lab.studies.{name}"]


def refused(command: list[str], out: Path, says: str, *options: str) -> None:
    """The command exits 2 with a one-line error that says `says`, and writes nothing to `out`."""
    done = subprocess.run([*command, str(out), *options], capture_output=True, text=True, cwd=ROOT)
    assert done.returncode == 2 and done.stderr.count("\n") == 1 and says in done.stderr, done.stderr
    assert not out.exists()


def summary(success: float, rmse: float, coverage: float, precision: float) -> dict:
    split = {"episodes": 20, "success_rate": success, "rmse": rmse, "coverage_rmse": coverage,
             "precision_rmse": precision, "predict_seconds": 0.5, "sim_seconds": 4.0, "failed_runs": 0}
    return {"summary": {"checkpoint": "runs/x/best", "task": "hangproccloth-multimodal", "command": "tax3d eval ...",
                        "machine": "test", "date": "2026-01-01", "policy_offset": [0.0, 0.0, 0.0],
                        "splits": {k: dict(split) for k in ("train", "unseen", "ood")}}}


def test_mode_spread(tmp_path):
    from tax3d.data.format import save_demo
    from tests.conftest import synthetic_demo

    folder = tmp_path / "data" / "unseen"
    folder.mkdir(parents=True)
    base = synthetic_demo(0)
    for i, shift in enumerate((0.0, 2.0)):  # one cloth, one pose, two goals 2.0 apart along x
        demo = dict(base, flow=base["flow"] + [shift, 0.0, 0.0])
        save_demo(folder / f"demo_{i}.npz", demo)
    save_demo(folder / "demo_2.npz", synthetic_demo(1) | {"rot": np.ones(3)})  # a cloth with one goal: skipped
    done = subprocess.run([*study("mode_spread"), "--data", str(tmp_path / "data")], capture_output=True, text=True,
                          cwd=ROOT)
    assert done.returncode == 0, done.stderr
    printed = json.loads(done.stdout)
    assert (printed["kind"], printed["version"]) == ("mode-spread", 1)
    split = printed["splits"]["unseen"]
    assert split["cloths_with_both_goals"] == 1
    assert abs(split["goal_separation_rmse"] - 2.0) < 1e-9 and abs(split["midpoint_rmse"] - 1.0) < 1e-9
    bad = subprocess.run([*study("mode_spread"), "--data", str(tmp_path / "no")], capture_output=True, text=True,
                         cwd=ROOT)
    assert bad.returncode == 2 and bad.stderr.count("\n") == 1


def test_success_by_rmse_bins_the_executed_goals(tmp_path):
    run = tmp_path / "eval-cd"
    run.mkdir()
    episodes = [{"split": split, "name": f"demo_{i}", "success": ok, "executed_rmse": r}
                for i, (split, ok, r) in enumerate([("unseen", True, 0.1), ("unseen", False, 0.2),
                                                    ("ood", True, 0.6), ("ood", False, 1.4), ("train", True, 0.9)])]
    (run / "results.json").write_text(json.dumps({**summary(0.5, 1.0, 0.5, 1.0), "episodes": episodes}))
    kept = tmp_path / "bins.json"
    done = subprocess.run([*study("success_by_rmse"), str(run), str(kept), "--edges", "0,0.5,1"],
                          capture_output=True, text=True, cwd=ROOT)
    assert done.returncode == 0, done.stderr
    data = json.loads(kept.read_text())
    assert data["kind"] == "success-by-rmse" and data["episodes"] == 4 and data["success_rate"] == 0.5  # train left out
    assert [(b["low"], b["high"], b["episodes"], b["success_rate"]) for b in data["bins"]] == [
        (0.0, 0.5, 2, 0.5), (0.5, 1.0, 1, 1.0), (1.0, None, 1, 0.0)]
    refused([*study("success_by_rmse"), str(run)], tmp_path / "x.json", "--edges 1,0.5", "--edges", "1,0.5")


def test_success_by_rmse_bins_by_the_error_at_the_grasped_vertices(tmp_path):
    run = tmp_path / "eval-cd"
    run.mkdir()
    episodes = [{"split": "unseen", "name": f"demo_{i}", "success": ok, "executed_rmse": 0.1, "executed_grip_error": g}
                for i, (ok, g) in enumerate([(True, 0.1), (True, 0.2), (False, 0.8), (False, None)])]
    (run / "results.json").write_text(json.dumps({**summary(0.5, 1.0, 0.5, 1.0), "episodes": episodes}))
    kept = tmp_path / "bins.json"
    done = subprocess.run([*study("success_by_rmse"), str(run), str(kept), "--edges", "0,0.5", "--by",
                           "executed_grip_error"], capture_output=True, text=True, cwd=ROOT)
    assert done.returncode == 0, done.stderr
    data = json.loads(kept.read_text())
    assert data["by"] == "executed_grip_error" and data["episodes"] == 3  # the episode without one left out
    assert [(b["episodes"], b["success_rate"]) for b in data["bins"]] == [(2, 1.0), (1, 0.0)]


def test_time_to_quality_collect_keeps_the_training_loss_between_validations(tmp_path):
    run = tmp_path / "run"
    run.mkdir()
    (run / "config.json").write_text(json.dumps({"data": {"train": ["t"], "val": ["v"]},
                                                 "train": {"val_demos": 20, "val_samples": 2}}))
    records = [{"step": 1, "loss": 9.0, "mse": 8.0, "seconds": 1.0, "plan": {"minutes": 2.0}},
               {"step": 2, "loss": 5.0, "mse": 4.0, "seconds": 30.0, "val_rmse": 1.5, "val_rmse_mean": 1.7},
               {"step": 3, "loss": 2.0, "mse": 1.0, "seconds": 60.0},
               {"step": 4, "loss": 4.0, "mse": 3.0, "seconds": 120.0, "val_rmse": 1.2, "val_rmse_mean": 1.3}]
    (run / "log.jsonl").write_text("".join(json.dumps(r) + "\n" for r in records))
    done = subprocess.run([*study("time_to_quality"), "--collect", "x", str(run), "tax3d train ...", "--out",
                           str(tmp_path / "out")], capture_output=True, text=True, cwd=ROOT)
    assert done.returncode == 0, done.stderr
    from lab.results import kept

    curve = kept.load(tmp_path / "out" / "time_to_quality.json", ("study",))["runs"]["x"]["curve"]
    assert [(p["step"], p["minutes"], p["train_mse"]) for p in curve] == [(2, 0.5, 6.0), (4, 2.0, 2.0)]




def test_subnormal(tmp_path):
    """benchmarks/subnormal.py times a run's own loss with and without subnormal floats and keeps what it measured."""
    from tests.conftest import tiny_model, write_demos

    run, data, out = tmp_path / "last", tmp_path / "demos", tmp_path / "subnormal.json"
    tiny_model().save_pretrained(run)
    write_demos(data, 2)
    script = [sys.executable, str(ROOT / "benchmarks" / "subnormal.py")]
    done = subprocess.run([*script, "--run", str(run), "--train", str(data), "--rounds", "2",
                           "--out", str(out)], capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-2000:]
    kept = json.loads(out.read_text())
    assert kept["kind"] == "train-step-benchmark" and kept["rounds"] == 2
    assert all(t > 0 for t in kept["forward_backward_seconds"].values()) and kept["speedup_flushed"] > 0
    refused([*script, "--run"], tmp_path / "missing", "no config.json", "--train", str(data))


def test_time_to_quality_refuses_more_threads_than_its_cores(tmp_path):
    """Each run's threads get cores of their own: asking for more than the program may use is refused before any
    training starts."""
    import os

    too_many = str(len(os.sched_getaffinity(0)) + 1)
    refused([*study("time_to_quality"), "--out"], tmp_path / "out", "--threads",
            "--minutes", "1", "--train", "t", "--val", "v", "--run", "a", "", "--threads", too_many)
