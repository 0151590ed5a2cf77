"""The scripts that keep the summaries `tax3d results` reads: keep_summary.py, keep_log.py, mode_spread.py,
val_curve.py, success_by_rmse.py, and the curves that benchmarks/time_to_quality.py keeps."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]


def refused(script: list[str], out: Path, says: str, *options: str) -> None:
    """The script exits 2 with a one-line error that says `says`, and writes nothing to `out`."""
    done = subprocess.run([sys.executable, *script, str(out), *options], capture_output=True, text=True)
    assert done.returncode == 2 and done.stderr.count("\n") == 1 and says in done.stderr, done.stderr
    assert not out.exists()


def summary(success: float, rmse: float, coverage: float, precision: float) -> dict:
    split = {"episodes": 20, "success_rate": success, "rmse": rmse, "coverage_rmse": coverage,
             "precision_rmse": precision, "predict_seconds": 0.5, "sim_seconds": 4.0, "failed_runs": 0}
    return {"summary": {"checkpoint": "runs/x/best", "task": "hangproccloth-multimodal", "command": "tax3d eval ...",
                        "machine": "test", "date": "2026-01-01", "policy_offset": [0.0, 0.0, 0.0],
                        "splits": {k: dict(split) for k in ("train", "unseen", "ood")}}}


def test_keep_summary_drops_the_episodes(tmp_path):
    run = tmp_path / "eval-rd"
    run.mkdir()
    (run / "results.json").write_text(json.dumps({**summary(0.5, 3.0, 2.9, 1.1), "episodes": []}))
    kept = tmp_path / "rd.json"
    done = subprocess.run([sys.executable, str(ROOT / "scripts" / "keep_summary.py"), str(run), str(kept)],
                          capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    data = json.loads(kept.read_text())
    assert "episodes" not in data and data["summary"]["splits"]["ood"]["coverage_rmse"] == 2.9


def test_keep_summary_keeps_the_splits_asked_for(tmp_path):
    run = tmp_path / "eval-cd"
    run.mkdir()
    (run / "results.json").write_text(json.dumps(summary(0.5, 3.0, 2.9, 1.1)))
    script = [sys.executable, str(ROOT / "scripts" / "keep_summary.py"), str(run)]
    done = subprocess.run([*script, str(tmp_path / "cd.json"), "--splits", "unseen,ood"], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    kept = json.loads((tmp_path / "cd.json").read_text())["summary"]
    assert list(kept["splits"]) == ["unseen", "ood"] and kept["kept_splits"] == "unseen,ood"
    done = subprocess.run([*script, str(tmp_path / "bad.json"), "--splits", "unseen,test"], capture_output=True, text=True)
    assert done.returncode == 2 and done.stderr.count("\n") == 1 and "test" in done.stderr
    assert not (tmp_path / "bad.json").exists()


def test_keep_log_keeps_the_plan_the_validations_and_the_last_step(tmp_path):
    run = tmp_path / "run"
    run.mkdir()
    lines = [{"step": 1, "loss": 2.0, "plan": {"steps": 5}}, {"step": 2, "loss": 1.5},
             {"step": 3, "loss": 1.0, "val_rmse": 0.75}, {"step": 4, "loss": 0.9}, {"step": 5, "loss": 0.8}]
    (run / "log.jsonl").write_text("".join(json.dumps(line) + "\n" for line in lines))
    script = [sys.executable, str(ROOT / "scripts" / "keep_log.py")]
    done = subprocess.run([*script, str(run), str(tmp_path / "log.json")], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    kept = json.loads((tmp_path / "log.json").read_text())
    assert [r["step"] for r in kept["records"]] == [1, 3, 5] and str(run / "log.jsonl") in kept["source"]
    refused([str(ROOT / "scripts" / "keep_log.py"), str(tmp_path / "nope")], tmp_path / "bad.json", "log.jsonl")


def test_keep_summary_bad_input(tmp_path):
    done = subprocess.run([sys.executable, str(ROOT / "scripts" / "keep_summary.py"), str(tmp_path / "nope"),
                           str(tmp_path / "out.json")], capture_output=True, text=True)
    assert done.returncode == 2
    assert done.stderr.count("\n") == 1 and "nope/results.json" in done.stderr
    assert not (tmp_path / "out.json").exists()


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
    done = subprocess.run([sys.executable, str(ROOT / "scripts" / "mode_spread.py"), "--data", str(tmp_path / "data")],
                          capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    split = json.loads(done.stdout)["splits"]["unseen"]
    assert split["cloths_with_both_goals"] == 1
    assert abs(split["goal_separation_rmse"] - 2.0) < 1e-9 and abs(split["midpoint_rmse"] - 1.0) < 1e-9
    bad = subprocess.run([sys.executable, str(ROOT / "scripts" / "mode_spread.py"), "--data", str(tmp_path / "no")],
                         capture_output=True, text=True)
    assert bad.returncode == 2 and bad.stderr.count("\n") == 1


def test_val_curve_kept(tmp_path):
    run = tmp_path / "run"
    run.mkdir()
    config = {"model": {"variant": "cp"}, "data": {"val": ["data/u/unseen"]},
              "train": {"val_demos": 10, "val_samples": 2, "steps": 1000}}
    (run / "config.json").write_text(json.dumps(config))
    log = [{"step": 20, "loss": 1.0, "seconds": 6.0}, {"step": 500, "loss": 0.5, "val_rmse": 2.5, "val_rmse_mean": 2.7,
                                                       "seconds": 300.0},
           {"step": 1000, "loss": 0.4, "val_rmse": 1.25, "val_rmse_mean": 1.5, "val_coverage_rmse": 0.75,
            "seconds": 600.0}]
    (run / "log.jsonl").write_text("".join(json.dumps(d) + "\n" for d in log))
    kept = tmp_path / "curve.json"
    done = subprocess.run([sys.executable, str(ROOT / "scripts" / "val_curve.py"), str(run), str(kept)],
                          capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    curve = json.loads(kept.read_text())
    assert [p["step"] for p in curve["points"]] == [500, 1000] and curve["points"][1]["minutes"] == 10.0
    assert curve["val_demos"] == 10 and curve["val"] == ["data/u/unseen"]
    assert "val_coverage_rmse" not in curve["points"][0] and curve["points"][1]["val_coverage_rmse"] == 0.75
    (run / "log.jsonl").write_text(json.dumps(log[0]) + "\n")
    refused([str(ROOT / "scripts" / "val_curve.py"), str(run)], tmp_path / "c2.json", "no validated step")


def test_success_by_rmse_bins_the_executed_goals(tmp_path):
    run = tmp_path / "eval-cd"
    run.mkdir()
    episodes = [{"split": split, "name": f"demo_{i}", "success": ok, "executed_rmse": r}
                for i, (split, ok, r) in enumerate([("unseen", True, 0.1), ("unseen", False, 0.2),
                                                    ("ood", True, 0.6), ("ood", False, 1.4), ("train", True, 0.9)])]
    (run / "results.json").write_text(json.dumps({**summary(0.5, 1.0, 0.5, 1.0), "episodes": episodes}))
    kept = tmp_path / "bins.json"
    script = str(ROOT / "scripts" / "success_by_rmse.py")
    done = subprocess.run([sys.executable, script, str(run), str(kept), "--edges", "0,0.5,1"],
                          capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    data = json.loads(kept.read_text())
    assert data["episodes"] == 4 and data["success_rate"] == 0.5  # train left out
    assert [(b["low"], b["high"], b["episodes"], b["success_rate"]) for b in data["bins"]] == [
        (0.0, 0.5, 2, 0.5), (0.5, 1.0, 1, 1.0), (1.0, None, 1, 0.0)]
    refused([script, str(run)], tmp_path / "x.json", "--edges 1,0.5", "--edges", "1,0.5")


def test_success_by_rmse_bins_by_the_error_at_the_grasped_vertices(tmp_path):
    run = tmp_path / "eval-cd"
    run.mkdir()
    episodes = [{"split": "unseen", "name": f"demo_{i}", "success": ok, "executed_rmse": 0.1, "executed_grip_error": g}
                for i, (ok, g) in enumerate([(True, 0.1), (True, 0.2), (False, 0.8), (False, None)])]
    (run / "results.json").write_text(json.dumps({**summary(0.5, 1.0, 0.5, 1.0), "episodes": episodes}))
    kept = tmp_path / "bins.json"
    script = str(ROOT / "scripts" / "success_by_rmse.py")
    done = subprocess.run([sys.executable, script, str(run), str(kept), "--edges", "0,0.5", "--by",
                           "executed_grip_error"], capture_output=True, text=True)
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
    done = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "time_to_quality.py"), "--collect", "x", str(run),
                           "tax3d train ...", "--out", str(tmp_path / "out")], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    curve = json.loads((tmp_path / "out" / "time_to_quality.json").read_text())["runs"]["x"]["curve"]
    assert [(p["step"], p["minutes"], p["train_mse"]) for p in curve] == [(2, 0.5, 6.0), (4, 2.0, 2.0)]


def load_script(name: str):
    import importlib.util

    spec = importlib.util.spec_from_file_location(name, ROOT / "scripts" / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_precision_parts_splits_a_miss_into_offset_and_shape():
    parts = load_script("precision_parts")
    rng = np.random.default_rng(0)
    goal = rng.normal(size=(50, 3))
    other = goal + [2.0, 0.0, 0.0]  # the other hole's goal, 2 apart along x
    shape = rng.normal(size=(50, 3)) * 0.1
    shape -= shape.mean(0)
    sample = goal + [0.5, 0.3, 0.0] + shape  # a quarter of the way toward the other goal, and off to the side
    p = parts.sample_parts(sample, [other, goal])
    assert abs(p["offset"] - np.hypot(0.5, 0.3)) < 1e-9 and abs(p["toward_other"] - 0.25) < 1e-9
    assert abs(p["shape_rmse"] - np.sqrt((shape**2).sum(-1).mean())) < 1e-9
    assert abs(p["precision_rmse"] ** 2 - p["offset"] ** 2 - p["shape_rmse"] ** 2) < 1e-9
    # an ideal denoiser leans halfway at pure noise and not at all once the mean of x_t tells the holes apart
    lean = lambda abar: parts.bayes_lean(2.7, abar, 256, np.random.default_rng(0))
    assert abs(lean(1e-8) - 0.5) < 0.01 and lean(0.1) < 1e-3 and lean(1e-8) > lean(0.002) > lean(0.01)


def test_precision_parts_refuses_bad_input(tmp_path):
    script = [sys.executable, str(ROOT / "scripts" / "precision_parts.py")]
    for args, says in ((["nope", "--data", str(tmp_path)], "no config.json"),
                       ([str(ROOT / "checkpoints" / "tax3d-cd-multimodal"), "--data", str(tmp_path / "no")], "--data"),
                       ([str(ROOT / "checkpoints" / "tax3d-cd-multimodal"), "--data", str(tmp_path), "--steps", "x"],
                        "--steps")):
        done = subprocess.run([*script, *args, "--out", str(tmp_path / "out.json")], capture_output=True, text=True)
        assert done.returncode == 2 and done.stderr.count("\n") == 1 and says in done.stderr, done.stderr
    assert not (tmp_path / "out.json").exists()


def test_precision_parts_runs_on_a_checkpoint(tmp_path):
    from tax3d.data.format import save_demo
    from tests.conftest import synthetic_demo, tiny_model

    tiny_model().save_pretrained(tmp_path / "ckpt")
    base = synthetic_demo(0, n=40)
    (tmp_path / "data").mkdir()
    for i, shift in enumerate((0.0, 2.0)):  # one cloth, one pose, a goal for each hole
        save_demo(tmp_path / "data" / f"demo_{i}.npz", dict(base, flow=base["flow"] + [shift, 0.0, 0.0]))
    done = subprocess.run([sys.executable, str(ROOT / "scripts" / "precision_parts.py"), str(tmp_path / "ckpt"),
                           "--data", str(tmp_path / "data"), "--samples", "2", "--steps", "20,5",
                           "--out", str(tmp_path / "parts.json")], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    out = json.loads((tmp_path / "parts.json").read_text())
    assert out["cloths"] == 1 and [row["t"] for row in out["from_noised_goal"]] == [5, 20]
    s = out["samples"]
    assert abs(s["precision_rmse"] ** 2 - s["offset"] ** 2 - s["shape_rmse"] ** 2) < 0.5 * s["precision_rmse"] ** 2
    assert all(np.isfinite(v) for row in out["from_noised_goal"] for v in row.values())
    (tmp_path / "data" / "demo_1.npz").unlink()  # one goal, as on unimodal: no lean toward another
    done = subprocess.run([sys.executable, str(ROOT / "scripts" / "precision_parts.py"), str(tmp_path / "ckpt"),
                           "--data", str(tmp_path / "data"), "--samples", "2", "--steps", "5"],
                          capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    out = json.loads(done.stdout)
    assert out["samples"]["toward_other"] is None and out["from_noised_goal"][0]["bayes_toward_other"] is None
    assert out["from_noised_goal"][0]["x0_rmse"] > 0
