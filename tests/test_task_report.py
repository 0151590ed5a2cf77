"""scripts/task_report.py and scripts/keep_summary.py: pages from kept evaluation summaries."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "scripts"))
import task_report  # noqa: E402


def summary(success: float, rmse: float, coverage: float, precision: float) -> dict:
    split = {"episodes": 20, "success_rate": success, "rmse": rmse, "coverage_rmse": coverage,
             "precision_rmse": precision, "predict_seconds": 0.5, "sim_seconds": 4.0, "failed_runs": 0}
    return {"summary": {"checkpoint": "runs/x/best", "task": "hangproccloth-multimodal", "command": "tax3d eval ...",
                        "machine": "test", "date": "2026-01-01", "policy_offset": [0.0, 0.0, 0.0],
                        "splits": {k: dict(split) for k in ("train", "unseen", "ood")}}}


def test_multimodal_page_has_coverage_and_precision(tmp_path):
    (tmp_path / "cd.json").write_text(json.dumps(summary(0.9, 1.5, 0.4, 0.6)))
    run = tmp_path / "eval-rd"
    run.mkdir()
    (run / "results.json").write_text(json.dumps({**summary(0.5, 3.0, 2.9, 1.1), "episodes": []}))
    kept = tmp_path / "rd.json"
    done = subprocess.run([sys.executable, str(ROOT / "scripts" / "keep_summary.py"), str(run), str(kept)],
                          capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    assert "episodes" not in json.loads(kept.read_text())
    out = tmp_path / "page.md"
    task_report.main(["--task", "hangproccloth-multimodal", "--eval", f"CD={tmp_path / 'cd.json'}", f"RD={kept}",
                      "--out", str(out)])
    text = out.read_text()
    assert "## Coverage and precision RMSE" in text
    assert "| TAX3D-CD (ours) | 0.400 | 0.400 | 0.400 | 0.600 | 0.600 | 0.600 |" in text
    assert "| RD (paper) | 2.978 | 2.987 | 3.057 | 1.296 | 1.087 | 1.114 |" in text  # appendix D.3
    assert "| RD (ours) | 3.000 | 3.000 | 3.000 | 0.50 | 0.50 | 0.50 | 20 / 20 / 20 |" in text
    assert "| TAX3D-CD (paper) | 1.413 | 1.532 | 1.610 | 0.95 | 0.98 | 0.73 | 64 / 40 / 40 |" in text


def test_unimodal_page_has_our_coverage_only(tmp_path):
    (tmp_path / "cp.json").write_text(json.dumps(summary(0.9, 0.5, 0.3, 0.5)))
    out = tmp_path / "page.md"
    task_report.main(["--task", "hangproccloth-unimodal", "--eval", f"CP={tmp_path / 'cp.json'}", "--out", str(out)])
    text = out.read_text()
    assert "| TAX3D-CP (ours) | 0.300 | 0.300 | 0.300 | 0.500 | 0.500 | 0.500 |" in text
    assert "| TAX3D-CP (paper) | 0.051 | 0.390 | 0.422 | 0.93 | 0.95 | 0.80 | 64 / 40 / 40 |" in text
    assert text.count("(paper) |") == 1  # the paper gives no coverage for this task
    assert "| TAX3D-CP (paper) | 0.051 | 0.390 | 0.422 | 0.93 | 0.95 | 0.80 | 64 / 40 / 40 |" in text


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


def test_val_curve_kept_and_shown(tmp_path):
    run = tmp_path / "run"
    run.mkdir()
    config = {"model": {"variant": "cp"}, "data": {"val": ["data/u/unseen"]},
              "train": {"val_demos": 10, "val_samples": 2, "steps": 1000}}
    (run / "config.json").write_text(json.dumps(config))
    log = [{"step": 20, "loss": 1.0, "seconds": 6.0}, {"step": 500, "loss": 0.5, "val_rmse": 2.5, "val_rmse_mean": 2.7,
                                                       "seconds": 300.0},
           {"step": 1000, "loss": 0.4, "val_rmse": 1.25, "val_rmse_mean": 1.5, "seconds": 600.0}]
    (run / "log.jsonl").write_text("".join(json.dumps(d) + "\n" for d in log))
    kept = tmp_path / "curve.json"
    done = subprocess.run([sys.executable, str(ROOT / "scripts" / "val_curve.py"), str(run), str(kept)],
                          capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    curve = json.loads(kept.read_text())
    assert [p["step"] for p in curve["points"]] == [500, 1000] and curve["points"][1]["minutes"] == 10.0
    (tmp_path / "cp.json").write_text(json.dumps(summary(0.9, 0.5, 0.3, 0.5)))
    out = tmp_path / "page.md"
    task_report.main(["--task", "hangproccloth-unimodal", "--eval", f"CP={tmp_path / 'cp.json'}",
                      "--curve", f"CP long={kept}", "--out", str(out)])
    text = out.read_text()
    assert "| step | CP long |" in text and "| 1,000 | 1.250 |" in text and "first 10 demos of `data/u/unseen`" in text
    (run / "log.jsonl").write_text(json.dumps(log[0]) + "\n")
    done = subprocess.run([sys.executable, str(ROOT / "scripts" / "val_curve.py"), str(run), str(tmp_path / "c2.json")],
                          capture_output=True, text=True)
    assert done.returncode == 2 and done.stderr.count("\n") == 1 and "no validated step" in done.stderr
    assert not (tmp_path / "c2.json").exists()
