"""The study at the paper's demonstration count: lab.studies.paper_count's arms and kept curves, and their page."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

from lab.results import kept
from lab.results.build import main
from lab.results.pages import plots
from tax3d.kept import stamp
from tests.conftest import write_demos

ROOT = Path(__file__).resolve().parents[1]
SMALL = ("--model.hidden_size 32 --model.depth 2 --model.num_heads 2 --data.num_action_points 16 "
         "--data.num_anchor_points 24 --train.num_workers 0 --train.batch_size 4")


def run(*argv) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "lab.studies.paper_count", *argv], capture_output=True, text=True,
                          cwd=ROOT)


def test_arms_train_side_by_side_and_keep_their_curves(tmp_path):
    write_demos(tmp_path / "train", 5)
    write_demos(tmp_path / "val", 2, seed=1)
    common = ["--task", "custom", "--train", str(tmp_path / "train"), "--num-train", "4", "--val", str(tmp_path / "val"),
              "--out", str(tmp_path / "out"), "--steps", "20", "--val-every", "10", "--keep-every", "20",
              "--val-demos", "2", "--val-samples", "1", "--keep", str(tmp_path / "keep.json"),
              "--arm", "plain", SMALL, "--arm", "scene", SMALL + " --data.rotate_scene True"]
    done = run(*common)
    assert done.returncode == 0, done.stderr
    study = kept.load(tmp_path / "keep.json", ("paper-count",))
    assert study["num_train"] == 4 and set(study["digests"]) == {"train", "val"}
    for name, arm in study["arms"].items():
        assert [p["step"] for p in arm["curve"]] == [10, 20]
        assert [p["samples"] for p in arm["curve"]] == [40, 80]  # steps x batch 4
        assert arm["kept_steps"] == [20] and (tmp_path / "out" / name / "steps" / "20" / "model.safetensors").is_file()
        assert arm["command"].startswith("tax3d train --preset cpu --model.variant cd ")
        assert "demo_3.npz" in arm["command"] and "demo_4.npz" not in arm["command"]  # the first 4 of 5
    assert json.loads((tmp_path / "out" / "scene" / "config.json").read_text())["data"]["rotate_scene"] is True

    (tmp_path / "keep.json").unlink()  # --collect writes the same curves from the logs, training nothing
    assert run(*common, "--collect").returncode == 0
    collected = kept.load(tmp_path / "keep.json", ("paper-count",))
    assert collected["arms"] == study["arms"] and collected["command"] == study["command"]
    assert "--collect" not in study["command"] and "--keep" in study["command"]
    assert study["command"].startswith("python -m lab.studies.paper_count --task custom ")


def test_bad_options_are_one_line_errors(tmp_path):
    for argv, words in ((["--arm", "a", "", "--arm", "a", "x"], "names must differ"),
                        (["--arm", "a", ""], "--val"), (["--arm", "a", "", "--collect"], "--collect needs --keep")):
        val = tmp_path / "missing" if words == "--val" else tmp_path
        done = run("--task", "custom", "--train", str(tmp_path), "--val", str(val), "--out", str(tmp_path / "o"),
                   *argv)
        assert done.returncode == 2 and len(done.stderr.strip().splitlines()) == 1 and words in done.stderr


def arm(samples_per_step: int, rmses: list[float]) -> dict:
    curve = [{"step": 100 * (i + 1), "samples": 100 * (i + 1) * samples_per_step, "hours": 0.1 * (i + 1),
              "val_rmse": r * 0.9, "val_rmse_mean": r, "train_mse": 0.01} for i, r in enumerate(rmses)]
    return {"options": "", "command": "tax3d train --preset cpu", "config": {}, "steps": curve[-1]["step"],
            "hours": curve[-1]["hours"], "samples_per_hour": 1, "kept_steps": [200], "curve": curve}


def test_the_page_draws_each_study_against_samples_with_the_papers_budget(tmp_path):
    root = tmp_path / "docs" / "results"
    (root / "pages").mkdir(parents=True)
    (root / "paper.toml").write_text("")
    (root / "pc").mkdir()
    study = {"study": "paper_count", "task": "custom", "num_train": 64, "preset": "cpu", "command": "python x.py",
             "train": "data/t", "val": "data/v", "val_demos": 20, "val_samples": 2,
             "digests": {"train": "a" * 64, "val": "b" * 64}, "machine": "m", "date": "2026-01-01",
             "cores_per_arm": 1, "arms": {"cpu": arm(16, [0.9, 0.6, 0.7]), "scene": arm(16, [0.95, 0.7, 0.5])}}
    (root / "pc" / "u.json").write_text(json.dumps(stamp("paper-count", 1, study)))
    (root / "pc" / "evals").mkdir()
    (root / "pc" / "evals" / "scene-200.json").write_text(json.dumps(stamp("eval", 1, {"summary": {
        "splits": {"val": {"success_rate": 0.825, "episodes": 40, "success_ci95": [0.68, 0.91]}}}})))
    (root / "pages" / "pc.toml").write_text('''kind = "paper-count"
title = "T"
page = "pc.md"
verdict = "cpu is lowest at {u.arms.cpu.best.val_rmse_mean:.3f}, scene ends at {u.arms.scene.end.val_rmse_mean:.3f}."
[[study]]
id = "u"
label = "unimodal"
summary = "pc/u.json"
plot = "pc/u.png"
evals = "pc/evals"
''')
    assert main(["--root", str(root)]) == 0
    page = (root / "pc.md").read_text()
    assert "cpu is lowest at 0.600, scene ends at 0.500." in page
    assert "| cpu | `(none)` | 4,800 (0.3) | 0.600 (3,200) | 0.700 |" in page
    assert "0.825 (0.68-0.91) of 40 at 200" in page and "not scored yet" in page
    source = plots.drawn_from((root / "pc" / "u.png").read_bytes())
    assert source["marks"] == [["the paper's budget", 8_000_000.0]]
    assert [r[0] for r in source["runs"]] == ["cpu", "scene"] and source["runs"][1][2] == [0.95, 0.7, 0.5]
    assert main(["--root", str(root), "--check"]) == 0
