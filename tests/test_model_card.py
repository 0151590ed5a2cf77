"""scripts/model_card.py: a checkpoint's card from its log and evaluation (the training study's section is built by
`tax3d results training`: tests/test_results.py)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from tests.conftest import tiny_model

ROOT = Path(__file__).resolve().parents[1]


def test_model_card_is_built_from_the_checkpoint_log_and_evaluation(tmp_path):
    checkpoint = tmp_path / "tax3d-cd-x"
    model = tiny_model()
    model.config.data.task = "hangproccloth-unimodal"
    model.config.data.train = ("data/unimodal/train256",)
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
    assert "- training demonstrations: `data/unimodal/train256` (made by the first command below)" in card
    assert "grasped vertices" not in card  # the uniform weight goes unmentioned


def test_model_card_of_a_run_s_last_weights_names_them_beside_the_lowest_validation(tmp_path):
    checkpoint = tmp_path / "tax3d-cd-x"
    model = tiny_model()
    model.config.data.task, model.config.data.grip_weight = "hangproccloth-multimodal", 16.0
    model.save_pretrained(checkpoint)
    log = tmp_path / "log.json"
    log.write_text(json.dumps({"records": [{"step": 2, "loss": 0.5, "seconds": 120.0, "val_rmse": 0.8},
                                           {"step": 3, "loss": 0.4, "seconds": 1800.0, "val_rmse": 0.9}]}))
    evaluation = tmp_path / "eval.json"
    evaluation.write_text(json.dumps({"summary": {
        "checkpoint": "runs/x/last", "task": "hangproccloth-multimodal", "date": "2026-01-01", "machine": "m",
        "command": "tax3d eval ...", "splits": {"unseen": {"episodes": 40, "success_rate": 0.5, "rmse": 1.0}}}}))
    done = subprocess.run([sys.executable, str(ROOT / "scripts" / "model_card.py"), str(checkpoint), "--log", str(log),
                           "--eval", str(evaluation), "--data-command", "DATA", "--train-command", "TRAIN"],
                          capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    card = (checkpoint / "README.md").read_text()
    assert "- last validation RMSE: 0.900 at step 3 (these weights, the run's last); lowest: 0.800 at step 2" in card
    assert "best validation RMSE" not in card
    assert "; the grasped vertices weigh 16 in the loss" in card


def test_model_card_of_a_run_whose_log_was_not_kept_says_so(tmp_path):
    checkpoint = tmp_path / "tax3d-cp-x"
    model = tiny_model()
    model.config.data.task, model.config.model.variant = "hangbag", "cp"
    model.config.train.steps, model.config.train.time_limit, model.config.train.threads = 4000, 45.0, 1
    model.save_pretrained(checkpoint)
    evaluation = tmp_path / "eval.json"
    evaluation.write_text(json.dumps({"summary": {"task": "hangbag", "date": "2026-01-01", "machine": "m",
                                                  "command": "tax3d eval ...", "splits": {
                                                      "ood": {"episodes": 40, "success_rate": 0.8, "rmse": 0.5}}}}))
    done = subprocess.run([sys.executable, str(ROOT / "scripts" / "model_card.py"), str(checkpoint),
                           "--eval", str(evaluation), "--data-command", "DATA", "--train-command", "TRAIN"],
                          capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    card = (checkpoint / "README.md").read_text()
    assert card.startswith("# TAX3D-CP for hangbag") and "| ood | 40 | 0.80 | 0.78 | 0.500 | 0.233 | - |" in card
    assert "- steps: a 4,000-step schedule, cut by a 45-minute limit on one core; the run's log was not kept" in card
    assert "wall time" not in card and "best validation" not in card


def test_model_card_of_a_checkpoint_trained_on_the_authors_data(tmp_path):
    checkpoint = tmp_path / "tax3d-cd-official"
    model = tiny_model()
    model.config.data.task, model.config.data.rotate = "hangproccloth-simple", True
    model.save_pretrained(checkpoint)
    evaluation, report = tmp_path / "eval.json", tmp_path / "official.json"
    evaluation.write_text(json.dumps({"summary": {"task": "hangproccloth-simple", "date": "2026-01-01", "machine": "m",
                                                  "command": "tax3d eval ...", "splits": {
                                                      "unseen": {"episodes": 40, "success_rate": 1.0, "rmse": 0.4}}}}))
    report.write_text(json.dumps({"command": "python scripts/official_report.py", "date": "2026-01-02",
                                  "machine": "n", "demos": 40, "samples": 5, "mean_goal_baseline_rmse": 1.1,
                                  "samplers": {"ddpm_100": {"rmse": 0.21, "rmse_min_of_samples": 0.19}}}))
    done = subprocess.run([sys.executable, str(ROOT / "scripts" / "model_card.py"), str(checkpoint), "--eval",
                           str(evaluation), "--official", str(report), "--data-command", "D", "--train-command", "T"],
                          capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    card = (checkpoint / "README.md").read_text()
    assert "trained on the authors' demonstrations" in card and "own demonstrations" not in card
    # beside the paper's TAX3D-CD on simple, unseen (appendix D.1): RMSE 0.255
    assert "| this checkpoint, 100-step DDPM | 0.210 | 0.190 |" in card and "| the paper (`unseen`) | 0.255 | - |" in card
    assert "| mean goal of `train` (the floor) | 1.100 | - |" in card
    assert "rotation augmentation" in card and "without rotation" not in card


@pytest.mark.parametrize("broken,says", [("eval", "a kept `tax3d eval` summary"),
                                         ("official", "scripts/official_report.py's JSON"),
                                         ("checkpoint", "config.json has a 'data' section")])
def test_model_card_bad_input_is_one_line_naming_the_file(tmp_path, broken, says):
    checkpoint = tmp_path / "ckpt"
    tiny_model().save_pretrained(checkpoint)
    files = {"eval": tmp_path / "eval.json", "official": tmp_path / "official.json"}
    files["eval"].write_text(json.dumps({"summary": {}}))
    files["official"].write_text(json.dumps({"samplers": {}}))
    target = checkpoint / "config.json" if broken == "checkpoint" else files[broken]
    target.write_text("{not json")
    done = subprocess.run([sys.executable, str(ROOT / "scripts" / "model_card.py"), str(checkpoint), "--eval",
                           str(files["eval"]), "--official", str(files["official"]), "--data-command", "D",
                           "--train-command", "T"], capture_output=True, text=True)
    assert done.returncode == 2 and len(done.stderr.strip().splitlines()) == 1
    assert done.stderr.startswith(f"error: {target}: not readable") and says in done.stderr
    assert not (checkpoint / "README.md").exists()
