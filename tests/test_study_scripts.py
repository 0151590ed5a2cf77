"""The scripts that turn kept results into pages: the training study's table and plot, and a checkpoint's card."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

from tests.conftest import tiny_model

ROOT = Path(__file__).resolve().parents[1]


def study(curves: dict[str, list[tuple[float, float]]]) -> dict:
    return {"machine": "m", "date": "d", "val": ["v"], "val_demos": 20, "val_samples": 2, "runs": {
        name: {"options": f"--opt {name}", "steps_per_minute": 100.0, "plan": {"step_seconds": 0.5},
               "curve": [{"minutes": m, "step": int(m * 100), "val_rmse": r, "val_rmse_mean": r} for m, r in curve]}
        for name, curve in curves.items()}}


def test_training_study_fills_its_section_from_the_json(tmp_path):
    path = tmp_path / "ttq-1.json"
    path.write_text(json.dumps(study({"a": [(14, 2.0), (29, 1.5), (61, 0.9)], "b": [(20, 1.2), (65, 0.7)]})))
    floor = tmp_path / "floor.json"
    floor.write_text(json.dumps({"rmse_mean_goal_baseline": 1.7}))
    page = tmp_path / "training.md"
    page.write_text("# T\n\nbefore\n<!-- study -->\nold\n<!-- /study -->\nafter\n")
    plot = tmp_path / "plot.png"
    done = subprocess.run([sys.executable, str(ROOT / "scripts" / "training_study.py"), str(path), "--floor",
                           str(floor), "--page", str(page), "--plot", str(plot)], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    text = page.read_text()
    assert text.startswith("# T\n\nbefore\n<!-- study -->\n") and text.endswith("<!-- /study -->\nafter\n")
    assert "old" not in text and plot.stat().st_size > 1000
    assert "Best at the end of its run: ttq-1: b, validation RMSE 0.700 after 65 minutes" in text
    row_a = next(line for line in text.splitlines() if line.startswith("| ttq-1 | a |"))
    # 15 min: the validation at 14; 30: at 29; 60: at 61 (within 10%); whole-run and first-steps rates
    assert "| 2.000 (14 min) | 1.500 (29 min) | 0.900 (61 min) | 0.900 (61 min) | 100 | 120 |" in row_a


def test_model_card_is_built_from_the_checkpoint_log_and_evaluation(tmp_path):
    checkpoint = tmp_path / "tax3d-cd-x"
    model = tiny_model()
    model.config.data.task = "hangproccloth-unimodal"
    model.save_pretrained(checkpoint)
    log = tmp_path / "log.jsonl"
    log.write_text("".join(json.dumps(r) + "\n" for r in [
        {"step": 1, "loss": 1.0, "seconds": 1.0, "plan": {"minutes": 30.0}},
        {"step": 2, "loss": 0.5, "seconds": 120.0, "val_rmse": 0.8},
        {"step": 3, "loss": 0.4, "seconds": 1800.0, "val_rmse": 0.6}]))
    summary = {"summary": {"task": "hangproccloth-unimodal", "date": "2026-01-01", "machine": "m",
                           "command": "tax3d eval ...", "splits": {
                               "unseen": {"episodes": 40, "success_rate": 0.875, "rmse": 0.61, "coverage_rmse": 0.3},
                               "ood": {"episodes": 40, "success_rate": 0.5, "rmse": 0.9, "coverage_rmse": None}}}}
    evaluation = tmp_path / "eval.json"
    evaluation.write_text(json.dumps(summary))
    done = subprocess.run([sys.executable, str(ROOT / "scripts" / "model_card.py"), str(checkpoint), "--log", str(log),
                           "--eval", str(evaluation), "--data-command", "DATA", "--train-command", "TRAIN"],
                          capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    card = (checkpoint / "README.md").read_text()
    assert card.startswith("# TAX3D-CD for hangproccloth-unimodal")
    # beside the paper's TAX3D-CD on unimodal (appendix D.2): success 0.90 / 0.85, RMSE 0.405 / 0.395
    assert "| unseen | 40 | 0.88 | 0.90 | 0.610 | 0.405 | 0.300 |" in card
    assert "| ood | 40 | 0.50 | 0.85 | 0.900 | 0.395 | - |" in card
    assert "- steps: 3 (planned for 30 minutes)" in card and "- wall time: 30 minutes" in card
    assert "best validation RMSE: 0.600 at step 3" in card and "DATA\nTRAIN" in card
