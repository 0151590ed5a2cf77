"""The training command: learning one demonstration, outputs, resuming after a kill, and bad input."""

from __future__ import annotations

import math
import time

import numpy as np
import pytest
import torch
from safetensors.torch import load_file

from tax3d import config as cfg
from tax3d.checkpoint import STATE_NAME
from tax3d.cli import train
from tax3d.training import batches, budget, validation
from tax3d.training import tax3d as learner
from tax3d.cli import main
from tax3d.data.format import load_demo, save_demo
from tax3d.metrics import rmse
from tax3d.model.tax3d import Tax3D
from tax3d.training.budget import Plan
from tax3d.variants import VARIANTS

from tests.conftest import TINY, read_log, synthetic_demo, write_demos

def test_overfits_one_demonstration(tmp_path, capsys):
    folder = tmp_path / "one"
    folder.mkdir()
    save_demo(folder / "demo_0.npz", synthetic_demo(3))
    out = tmp_path / "run"
    code = main(["train", *TINY, "--out", str(out), "--data.train", str(folder), "--data.val", str(folder),
                 "--train.steps", "800", "--train.val_every", "800", "--train.warmup_steps", "20",
                 "--data.subsets", "0",  # fresh points each step: the loop alone
                 "--data.grip_weight", "1"])  # every point alike: this demo's goals are independent per point
    assert code == 0
    demo = load_demo(folder / "demo_0.npz")
    goal = demo["action_pc"] + demo["flow"]
    model = Tax3D.from_pretrained(out / "best")
    # every point through the network: this synthetic demo's goals are independent per point, so carrying a
    # sampled point's displacement to its neighbours (the default above the training size) cannot fit them
    goals = model.predict(demo["action_pc"], demo["anchor_pc"], num_samples=4, seed=0, max_points=0)
    # the trivial predictions: the untrained network (zero cross-displacement in the anchor frame), and no motion
    untrained = Tax3D(model.config).predict(demo["action_pc"], demo["anchor_pc"], seed=0)
    trivial = min(float(rmse(untrained[0], goal)), float(rmse(demo["action_pc"], goal)))
    assert float(rmse(goals, goal).mean()) < 0.2 * trivial
    log = read_log(out)
    assert [r["step"] for r in log] == list(range(1, 801)) and "val_rmse" in log[-1]
    assert {"loss", "mse", "vb", "lr", "seconds"} <= set(log[0])



def test_trains_and_predicts_on_the_core_keys_alone(tmp_path, capsys):
    """Demonstrations holding only action_pc, anchor_pc and flow (written with write_demo) train, validate and
    predict; with grip_weight the run says once that they name no grasped vertices."""
    import json

    from tax3d.data import write_demo

    rng = np.random.default_rng(0)
    for i in range(3):
        demo = synthetic_demo(rng)
        write_demo(tmp_path / "mine" / f"demo_{i}.npz", demo["action_pc"], demo["anchor_pc"],
                   goal=demo["action_pc"] + demo["flow"])
    out = tmp_path / "run"
    assert main(["train", *TINY, "--out", str(out), "--data.train", str(tmp_path / "mine"), "--data.val",
                 str(tmp_path / "mine"), "--train.steps", "4", "--train.val_every", "4",
                 "--data.grip_weight", "4"]) == 0
    assert "name no grasped vertices" in capsys.readouterr().err
    assert "val_rmse" in read_log(out)[-1] and "val_grip_error" not in read_log(out)[-1]
    assert main(["predict", "--checkpoint", str(out / "best"), "--demos", str(tmp_path / "mine"), "--samples", "2",
                 "--steps", "2", "--out", str(tmp_path / "pred.npz")]) == 0
    assert json.loads(capsys.readouterr().out.strip().splitlines()[-1])["demos"] == 3
    assert np.load(tmp_path / "pred.npz")["goals"].shape[:2] == (3, 2)


def test_the_run_records_the_task_its_demos_name(tmp_path, demos, capsys):
    """config.json's data.task: the task the files name; "custom" where none names one; --data.task where the files
    say nothing; files naming two tasks, or another than --data.task, are a one-line error before training."""
    from tests.conftest import one_line_error

    named = tmp_path / "named"
    named.mkdir()
    for i in range(2):
        save_demo(named / f"demo_{i}.npz", {**synthetic_demo(i), "task": "hangbag"})
    base = ["train", *TINY, "--train.steps", "1", "--train.val_every", "1"]
    recorded = {}
    for name, extra in (("custom", []), ("given", ["--data.task", "hangproccloth-unimodal"]), ("named", [])):
        data = named if name == "named" else demos
        assert main([*base, "--out", str(tmp_path / name), "--data.train", str(data), *extra]) == 0
        recorded[name] = cfg.load(tmp_path / name / "config.json").data.task
        assert cfg.load(tmp_path / name / "last" / "config.json").data.task == recorded[name]
    assert recorded == {"custom": "custom", "given": "hangproccloth-unimodal", "named": "hangbag"}
    capsys.readouterr()
    one_line_error(capsys, [*base, "--out", tmp_path / "mixed", "--data.train", demos, named], "names task 'none'",
                   "'hangbag'", "expected demonstrations of one task")
    one_line_error(capsys, [*base, "--out", tmp_path / "other", "--data.train", named, "--data.task",
                            "hangproccloth-simple"], "--data.task hangproccloth-simple", "task 'hangbag'")
    assert not (tmp_path / "mixed").exists() and not (tmp_path / "other").exists()

def test_outputs_and_config(tmp_path, demos):
    out = tmp_path / "run"
    assert main(["train", *TINY, "--out", str(out), "--data.train", str(demos), "--model.variant", "CP-W",
                 "--train.steps", "6", "--train.val_every", "3", "--data.val", str(demos)]) == 0
    config = cfg.load(out / "config.json")
    assert config.model.variant == "cp_w" and config.model.hidden_size == 32 and config.train.steps == 6
    assert config.train.lr == cfg.cpu().train.lr  # preset values survive where no option is given
    assert sorted(p.name for p in (out / "best").iterdir()) == ["config.json", "model.safetensors"]
    assert sorted(p.name for p in (out / "last").iterdir()) == ["config.json", "model.safetensors",
                                                                STATE_NAME]
    state = torch.load(out / "last" / STATE_NAME, weights_only=True)
    assert state["step"] == 6
    # the kept JSON: every validation and the last step, readable as a validation curve
    from lab.results import kept

    summary = kept.load(out / "summary.json", ("train-log",))
    assert [p["step"] for p in summary["points"]] == [3, 6] and summary["records"][-1]["step"] == 6
    assert summary["variant"] == "cp_w" and summary["val"] == [str(demos)] and summary["last_step"] == 6
    assert summary["machine"] and summary["date"] and summary["command"].startswith("tax3d train ")
    assert "--model.variant CP-W" in summary["command"]  # as typed
    assert float(torch.tensor([1e-39]) * 1.0) == 0.0  # training flushes subnormal floats to zero
    assert not [p for p in out.iterdir() if p.name.startswith(".")]  # no temporary folders left


def test_keep_every_keeps_the_weights_of_those_validations(tmp_path, demos):
    out = tmp_path / "run"
    assert main(["train", *TINY, "--out", str(out), "--data.train", str(demos), "--data.val", str(demos),
                 "--train.steps", "6", "--train.val_every", "2", "--train.keep_every", "4"]) == 0
    assert sorted(p.name for p in (out / "steps").iterdir()) == ["4"]
    kept_weights = load_file(out / "steps" / "4" / "model.safetensors")
    assert cfg.load(out / "steps" / "4" / "config.json").train.keep_every == 4
    assert any(not torch.equal(v, load_file(out / "last" / "model.safetensors")[k]) for k, v in kept_weights.items())


@pytest.mark.parametrize("variant", VARIANTS)
def test_every_variant_trains_and_predicts(tmp_path, demos, variant):
    out = tmp_path / variant
    assert main(["train", *TINY, "--out", str(out), "--data.train", str(demos), "--model.variant", variant,
                 "--train.steps", "2", "--train.val_every", "2", "--data.val", str(demos)]) == 0
    assert np.isfinite(read_log(out)[-1]["val_rmse"])
    model = Tax3D.from_pretrained(out / "best")
    assert model.spec.name == variant
    demo = load_demo(demos / "demo_0.npz")
    goals = model.predict(demo["action_pc"], demo["anchor_pc"], num_samples=3, seed=0)
    assert goals.shape == (3, *demo["action_pc"].shape) and np.isfinite(goals).all()


def test_resume_after_a_kill_matches_an_uninterrupted_run(tmp_path, demos, monkeypatch):
    args = [*TINY, "--data.train", str(demos), "--train.steps", "12", "--train.val_every", "5",
            "--train.ema", "0.9", "--data.rotate", "True"]
    assert main(["train", *args, "--out", str(tmp_path / "whole")]) == 0

    # Kill the second run while it loads the batch of step 8 (its last checkpoint is at step 5) ...
    calls = {"n": 0}
    getitem = batches.EpochItems.__getitem__

    def dying(self, key):
        calls["n"] += 1
        if calls["n"] > 7 * 8:
            raise KeyboardInterrupt
        return getitem(self, key)

    monkeypatch.setattr(batches.EpochItems, "__getitem__", dying)
    assert main(["train", *args, "--out", str(tmp_path / "killed")]) == 130
    assert [r["step"] for r in read_log(tmp_path / "killed")][-1] == 7
    monkeypatch.setattr(batches.EpochItems, "__getitem__", getitem)
    # ... and resume it: the same losses, step for step, and the same weights
    assert main(["train", *args, "--out", str(tmp_path / "killed"), "--resume"]) == 0
    whole, resumed = read_log(tmp_path / "whole"), read_log(tmp_path / "killed")
    assert [r["step"] for r in resumed] == list(range(1, 13))
    for a, b in zip(whole, resumed):
        assert a["loss"] == b["loss"] and a["lr"] == b["lr"] and a.get("val_rmse") == b.get("val_rmse")
    for name in ("last",):
        w1 = load_file(tmp_path / "whole" / name / "model.safetensors")
        w2 = load_file(tmp_path / "killed" / name / "model.safetensors")
        assert all(torch.equal(w1[k], w2[k]) for k in w1)



@pytest.mark.slow
@pytest.mark.parametrize("signum", ["SIGINT", "SIGTERM"])
def test_ctrl_c_saves_last_and_the_rerun_resumes_there(tmp_path, demos, signum):
    """SIGINT (a terminal's Ctrl-C) or SIGTERM (a scheduler preempting the job) to a real `tax3d train`, its whole
    process group, data worker included: last/ is written at the step reached, the run says which, exits 130; the
    rerun resumes there and says so, and the log holds each step once."""
    import os
    import signal
    import subprocess
    import sys
    import time
    from pathlib import Path

    out = tmp_path / "run"
    command = [sys.executable, "-m", "tax3d.cli", "train", *TINY, "--out", str(out), "--data.train", str(demos),
               "--train.val_every", "1000000", "--train.num_workers", "1"]
    env = {**os.environ, "PYTHONPATH": str(Path(train.__file__).parents[2]), "OMP_NUM_THREADS": "1"}
    run = subprocess.Popen([*command, "--train.steps", "1000000"], env=env, stderr=subprocess.PIPE, text=True,
                           start_new_session=True)
    deadline = time.time() + 120
    while time.time() < deadline and not ((out / "log.jsonl").is_file() and len(read_log(out)) >= 3):
        time.sleep(0.2)
    os.killpg(run.pid, getattr(signal, signum))
    err = run.communicate(timeout=120)[1]
    assert run.returncode == 130, err[-2000:]
    step = torch.load(out / "last" / STATE_NAME, weights_only=True)["step"]
    assert step >= 3 and f"interrupted at step {step} of 1000000: saved {out / 'last'}" in err
    assert "tax3d train: interrupted" in err and "Traceback" not in err
    assert [r["step"] for r in read_log(out)] == list(range(1, step + 1))

    # the same command again, stopped the same way after a few more steps
    again = subprocess.Popen([*command, "--train.steps", "1000000"], env=env, stderr=subprocess.PIPE, text=True,
                             start_new_session=True)
    deadline = time.time() + 120
    while time.time() < deadline and len(read_log(out)) < step + 2:
        time.sleep(0.2)
    os.killpg(again.pid, getattr(signal, signum))
    err = again.communicate(timeout=120)[1]
    assert again.returncode == 130 and f"resuming {out} at step {step}" in err, err[-2000:]
    end = torch.load(out / "last" / STATE_NAME, weights_only=True)["step"]
    assert end >= step + 2 and [r["step"] for r in read_log(out)] == list(range(1, end + 1))


def test_a_fresh_start_starts_a_fresh_log(tmp_path, demos):
    out = tmp_path / "run"
    out.mkdir()
    (out / "log.jsonl").write_text('{"step": 1, "loss": 9.0}\n{"step": 2, "loss": 9.0}\n')  # a run without last/
    assert main(["train", *TINY, "--out", str(out), "--data.train", str(demos), "--train.steps", "2",
                 "--train.val_every", "2"]) == 0
    assert [r["step"] for r in read_log(out)] == [1, 2] and read_log(out)[0]["loss"] != 9.0

def run_cli(capsys, *argv):
    code = main(list(argv))
    return code, capsys.readouterr().err.strip()


def test_bad_input(tmp_path, demos, capsys):
    out = tmp_path / "run"
    empty = tmp_path / "empty"
    empty.mkdir()
    nan = tmp_path / "nan"
    nan.mkdir()
    demo = synthetic_demo(0)
    demo["flow"][3, 1] = np.nan
    np.savez(nan / "demo_0.npz", **{k: (np.array(v, dtype=object) if isinstance(v, dict) else v)
                                    for k, v in demo.items()})
    shapes = tmp_path / "shapes"
    shapes.mkdir()
    demo = synthetic_demo(0)
    demo["flow"] = demo["flow"][:5]
    np.savez(shapes / "demo_0.npz", **{k: (np.array(v, dtype=object) if isinstance(v, dict) else v)
                                       for k, v in demo.items()})
    base = ["train", *TINY, "--train.steps", "2", "--train.val_every", "2"]
    cases = [
        ([*base, "--out", str(out)], "--data.train"),
        ([*base, "--out", str(out), "--data.train", str(empty)], "no demo_N.npz files"),
        ([*base, "--out", str(out), "--data.train", str(tmp_path / "nope")], "no such demonstration folder"),
        ([*base, "--out", str(out), "--data.train", str(nan)], "NaN"),
        ([*base, "--out", str(out), "--data.train", str(shapes)], "flow has shape"),
        ([*base, "--out", str(out), "--data.train", str(demos), "--data.val", str(empty)], "no demo_N.npz files"),
        ([*base, "--out", str(out), "--data.train", str(demos), "--model.variant", "xx"], "unknown variant"),
        ([*base, "--out", str(out), "--data.train", str(demos), "--model.num_heads", "3"], "num_heads"),
        ([*base, "--out", str(tmp_path / "fresh"), "--data.train", str(demos), "--resume"], "--resume"),
    ]
    for argv, message in cases:
        code, err = run_cli(capsys, *argv)
        assert code == 2, argv
        assert message in err and len(err.splitlines()) == 1, err
    # a finished run, then a different variant or network in the same folder
    assert main([*base, "--out", str(out), "--data.train", str(demos)]) == 0
    capsys.readouterr()
    for flag, value in (("--model.variant", "cp"), ("--model.depth", "3")):
        code, err = run_cli(capsys, *base, "--out", str(out), "--data.train", str(demos), flag, value)
        assert code == 2 and flag in err and len(err.splitlines()) == 1, err


def test_data_workers_do_not_change_the_run(tmp_path, demos):
    """Samples are seeded by (seed, epoch, index), so `--train.num_workers` changes the speed alone."""
    args = [*TINY, "--data.train", str(demos), "--train.steps", "6", "--train.val_every", "6",
            "--data.rotate", "True", "--data.val", str(demos)]
    assert main(["train", *args, "--out", str(tmp_path / "w0")]) == 0
    assert main(["train", *args, "--train.num_workers", "2", "--out", str(tmp_path / "w2")]) == 0
    w0, w2 = read_log(tmp_path / "w0"), read_log(tmp_path / "w2")
    assert [r["loss"] for r in w0] == [r["loss"] for r in w2] and w0[-1]["val_rmse"] == w2[-1]["val_rmse"]


def test_schedule_never_rises_after_the_warm_up():
    c = cfg.cpu().train
    lrs = [Plan.of(c).lr_at(step) for step in range(c.steps + 50)]
    assert lrs[c.warmup_steps - 1] == pytest.approx(c.lr)
    after = np.array(lrs[c.warmup_steps - 1:])
    assert (np.diff(after) <= 1e-15).all() and after[-1] == 0.0


def test_ema_decay_warms_up():
    """The average's decay starts near 0.1, so it follows the early weights, and reaches the set decay later."""
    assert learner.ema_decay(0, 0.999) == pytest.approx(0.1)
    decays = [learner.ema_decay(s, 0.999) for s in range(20000)]
    assert (np.diff(decays) >= 0).all() and decays[-1] == 0.999
    assert learner.ema_decay(100, 0.999) < 0.92  # without warm-up the average would keep ~90% of the initial weights
    assert learner.ema_decay(20, 0.5) == 0.5


class _FixedSamples:
    """Stands in for a model in `validate`: returns the samples it was given, scene by scene."""

    training = False

    def __init__(self, samples):
        self.samples = samples

    def eval(self):
        return self

    def train(self, mode=True):
        return self

    def predict_scenes(self, scenes, **_):
        return self.samples[: len(scenes)]


def test_validation_reports_coverage_where_demos_share_an_observation():
    """Two demos of one cloth (one per hole) share their clouds: each goal is covered by the other's sample."""
    cloth, other = synthetic_demo(0), synthetic_demo(1)
    first = {**cloth, "flow": cloth["flow"]}
    second = {**cloth, "flow": cloth["flow"] + 3.0}  # the other hole: every point 3 units off the first goal
    goal = [d["action_pc"] + d["flow"] for d in (first, second, other)]
    samples = [np.stack([goal[1], goal[1]]), np.stack([goal[0], goal[0]]), np.stack([goal[2] + 1.0] * 2)]
    record = validation.validate(_FixedSamples(samples), [first, second, other], num_samples=2, seed=0)
    assert record["val_rmse"] == pytest.approx((2 * 3 * 3**0.5 + 3**0.5) / 3)  # both cloth samples at the wrong hole
    assert record["val_coverage_rmse"] == pytest.approx(3**0.5 / 2)  # the cloth covered exactly, the other not
    assert record["val_precision_rmse"] == pytest.approx(3**0.5 / 2)  # every cloth sample lies on one of its goals
    one_hole = [np.stack([goal[0], goal[0]]), np.stack([goal[0], goal[0]]), samples[2]]
    record = validation.validate(_FixedSamples(one_hole), [first, second, other], num_samples=2, seed=0)
    assert record["val_precision_rmse"] == pytest.approx(3**0.5 / 2)  # precise, though only one hole is covered
    assert record["val_coverage_rmse"] == pytest.approx((3 * 3**0.5 / 2 + 3**0.5) / 2)
    assert validation.scene_groups([(d["action_pc"], d["anchor_pc"]) for d in (first, other, second)]) == [[0, 2], [1]]
    assert "val_coverage_rmse" not in validation.validate(_FixedSamples(samples[2:]), [other], num_samples=2, seed=0)


def test_validation_reports_the_error_at_the_grasped_vertices():
    """val_grip_error: the mean distance, over samples, at the demo's gripper vertices only."""
    demo = synthetic_demo(0)
    grip = [v for g in demo["anchors"].values() for v in g["vertices"]]
    goal = demo["action_pc"] + demo["flow"]
    off_grip, at_grip = goal.copy(), goal.copy()
    off_grip[[i for i in range(len(goal)) if i not in grip]] += 5.0
    at_grip[grip] += np.array([0.0, 0.0, 2.0])
    assert validation.validate(_FixedSamples([np.stack([off_grip, goal])]), [demo], 2, 0)["val_grip_error"] == 0.0
    assert validation.validate(_FixedSamples([np.stack([at_grip, goal])]), [demo], 2, 0)["val_grip_error"] == \
        pytest.approx(1.0)


def fake_step_clock(monkeypatch, seconds) -> None:
    """train's clock advances by seconds(n) at the n-th step (1-based) and stands still otherwise."""
    clock = {"now": 1000.0, "steps": 0}
    monkeypatch.setattr(time, "time", lambda: clock["now"])
    step_loss = learner.TrainingLoss.forward

    def timed(self, *a):
        clock["steps"] += 1
        clock["now"] += seconds(clock["steps"])
        return step_loss(self, *a)

    monkeypatch.setattr(learner.TrainingLoss, "forward", timed)


PLANNED = ["--train.minutes", "0.5", "--train.validations", "3", "--train.warmup_steps", "10"]


def test_minutes_plan_fixes_steps_and_resume_keeps_them(tmp_path, demos, monkeypatch):
    """--train.minutes measures the step rate, fixes train.steps and val_every (recorded in config.json and the
    log) and a resumed run continues the same plan."""
    fake_step_clock(monkeypatch, lambda n: 0.5)  # every step takes half a second of this fake clock
    out = tmp_path / "planned"
    args = ["train", *TINY, "--out", str(out), "--data.train", str(demos), "--data.val", str(demos), *PLANNED]
    assert main(args) == 0
    log = read_log(out)
    plan = next(r["plan"] for r in log if "plan" in r)
    # 30 s at 0.5 s a step, validations taking no time on this clock: 60 steps in all
    assert plan["steps"] == 60 and plan["val_every"] == 20 and plan["step_seconds"] == pytest.approx(0.5)
    assert cfg.load(out / "config.json").train.steps == 60 and log[-1]["step"] == 60
    assert [r["step"] for r in log if "val_rmse" in r] == [20, 40, 60] and not any("replan" in r for r in log)
    assert all(r["lr"] <= plan_lr for r, plan_lr in zip(log[10:], [r["lr"] for r in log[9:]]))
    # more minutes on resume do not re-plan a run that is already planned
    assert main(args) == 0
    assert read_log(out)[-1]["step"] == 60


def test_the_bar_shows_no_total_until_the_plan(tmp_path, demos, monkeypatch, capsys):
    """Before a --train.minutes plan fixes the steps, the bar has no total (so no ETA from the preset's steps)."""
    import re

    fake_step_clock(monkeypatch, lambda n: 0.5)
    assert main(["train", *TINY, "--out", str(tmp_path / "run"), "--data.train", str(demos), "--data.val", str(demos),
                 *PLANNED]) == 0
    before, after = capsys.readouterr().err.split("planned 60 steps", 1)
    assert "train:" in before and not re.search(r"\d+/\d+", before)
    assert "/60" in after


@pytest.mark.parametrize("later, steps", [(1.0, 36), (0.25, 108)])
def test_minutes_plan_is_timed_again_at_the_first_validation(tmp_path, demos, monkeypatch, later, steps):
    """Timed again at the first validation, a plan whose steps have slowed (or sped up) since the warm-up is
    shortened (or lengthened) to end on time, recorded in config.json and the log line `replan`; the decay goes on
    from where it was, so the learning rate neither jumps nor rises."""
    fake_step_clock(monkeypatch, lambda n: 0.5 if n <= 12 else later)  # the plan is made at step 12
    out = tmp_path / "timed-again"
    assert main(["train", *TINY, "--out", str(out), "--data.train", str(demos), "--data.val", str(demos),
                 *PLANNED]) == 0
    log = read_log(out)
    assert next(r["plan"] for r in log if "plan" in r)["steps"] == 60
    # at step 20, 6 s + 8 steps have passed; the seconds left hold `steps` - 20 steps at the later rate
    replan = next(r["replan"] for r in log if "replan" in r)
    assert replan["steps"] == steps and replan["planned"] == 60 and replan["step_seconds"] == pytest.approx(later)
    saved = cfg.load(out / "config.json").train
    assert saved.steps == steps and log[-1]["step"] == steps and knee(out) == 20
    assert log[-1]["seconds"] == pytest.approx(30.0)
    lrs = [r["lr"] for r in log]
    assert all(b <= a for a, b in zip(lrs[10:], lrs[11:])) and lrs[-1] < 0.01 * max(lrs)
    # no jump at the re-plan: the step after it changes the rate by no more than the one before it
    assert abs(lrs[20] - lrs[19]) <= 1.5 * abs(lrs[19] - lrs[18])


def test_a_plan_is_timed_again_at_every_validation(tmp_path, demos, monkeypatch):
    """Steps that speed up only after the first validation still lengthen the plan at the next one."""
    fake_step_clock(monkeypatch, lambda n: 0.5 if n <= 20 else 0.25)
    out = tmp_path / "timed-again-later"
    assert main(["train", *TINY, "--out", str(out), "--data.train", str(demos), "--data.val", str(demos),
                 *PLANNED]) == 0
    log = read_log(out)
    assert [r["step"] for r in log if "replan" in r] == [40]  # at step 20 the rate is the plan's
    # at step 40, 15 s have passed; the 15 s left hold 60 more steps at 0.25 s
    assert log[-1]["step"] in (99, 100) and log[-1]["seconds"] == pytest.approx(30.0, abs=0.3)
    assert knee(out) == 40


def killed_at_step(step: int, monkeypatch, args: list[str]) -> None:
    """`tax3d train ARGS` killed while it loads the batch of `step` (TINY's batch of 8), as by a SIGKILL: last/
    stays at the validation before."""
    getitem = batches.EpochItems.__getitem__
    calls = {"n": 0}

    def dying(self, key):
        calls["n"] += 1
        if calls["n"] > (step - 1) * 8:
            raise KeyboardInterrupt
        return getitem(self, key)

    monkeypatch.setattr(batches.EpochItems, "__getitem__", dying)
    assert main(args) == 130
    monkeypatch.setattr(batches.EpochItems, "__getitem__", getitem)


def test_a_resumed_plan_is_timed_again_from_where_it_resumed(tmp_path, demos, monkeypatch):
    """A planned run killed after its first validation and resumed on a machine twice as fast re-plans at its next
    validation from the steps since the resume, so that its minutes in all still end on time."""
    fake_step_clock(monkeypatch, lambda n: 0.5)
    out = tmp_path / "resumed"
    args = ["train", *TINY, "--out", str(out), "--data.train", str(demos), "--data.val", str(demos), *PLANNED]
    killed_at_step(26, monkeypatch, args)  # last/ is at step 20, 10 s in
    fake_step_clock(monkeypatch, lambda n: 0.25)
    assert main([*args, "--resume"]) == 0
    log = read_log(out)
    # at step 40, 10 + 5 s have passed; the 15 s left hold 60 more steps at 0.25 s
    assert [(r["step"], r["replan"]["steps"]) for r in log if "replan" in r] == [(40, 100)]
    assert log[-1]["step"] == 100 and log[-1]["seconds"] == pytest.approx(30.0)
    assert cfg.load(out / "config.json").train.steps == 100 and knee(out) == 40


def test_a_run_resumed_after_a_replan_keeps_it(tmp_path, demos, monkeypatch):
    """last/ is written after the validation's re-plan: a run killed before its next validation resumes with the
    re-planned steps and knee, not with the plan from before them."""
    fake_step_clock(monkeypatch, lambda n: 0.5 if n <= 12 else 1.0)  # re-planned to 36 steps at step 20
    out = tmp_path / "replanned"
    args = ["train", *TINY, "--out", str(out), "--data.train", str(demos), "--data.val", str(demos), *PLANNED]
    killed_at_step(26, monkeypatch, args)
    assert knee(out) == 20 and cfg.load(out / "last" / "config.json").train.steps == 36
    fake_step_clock(monkeypatch, lambda n: 1.0)
    assert main([*args, "--resume"]) == 0
    log = read_log(out)
    assert log[-1]["step"] == 36 and log[-1]["seconds"] == pytest.approx(30.0) and knee(out) == 20


def knee(out) -> int:
    """The step of the last re-plan, in the run's training state."""
    return torch.load(out / "last" / "training_state.pt", weights_only=True)["plan"]["knee"]


def test_a_replanned_decay_goes_on_from_its_progress():
    plan = Plan.of(cfg.TrainConfig(lr=1.0, warmup_steps=10, steps=110))
    before = plan.lr_at(60)  # half way: lr / 2
    plan.knee_progress, plan.knee, plan.steps = plan.progress(60), 60, 260
    assert plan.lr_at(60) == pytest.approx(before) == pytest.approx(0.5)
    assert plan.lr_at(160) == pytest.approx(0.5 * (1 + math.cos(math.pi * 0.75)))
    assert plan.lr_at(260) == pytest.approx(0.0, abs=1e-12) and plan.lr_at(59) > before


def test_default_preset_fits_the_machine_and_long_runs_are_told(tmp_path, demos, capsys, monkeypatch):
    monkeypatch.setattr(budget, "LONG_RUN_HOURS", 0.0)
    args = [a for a in TINY if a not in ("--preset", "cpu")]
    assert main(["train", *args, "--out", str(tmp_path / "run"), "--data.train", str(demos),
                 "--train.steps", "30", "--train.val_every", "30", "--train.warmup_steps", "10"]) == 0
    err = capsys.readouterr().err
    expected = "paper" if torch.cuda.is_available() else "cpu-fast"
    assert f"--preset not given: using {expected}" in err
    assert "note: 30 steps at this machine's rate take about" in err
    assert "trained 30 steps in" in err and "weights in" in err  # the closing line
    assert cfg.load(tmp_path / "run" / "config.json").train.lr == cfg.preset(expected).train.lr


def test_a_cpu_fast_run_trains_on_128_points_and_predicts_and_validates_on_256(tmp_path):
    """cpu-fast: batch 8 on 128 + 128 points; its weights predict with the network on 256 action points, and its
    validation runs the network on the same 256, as predict does."""
    write_demos(tmp_path / "demos", 3, n=300, m=200)
    out = tmp_path / "run"
    assert main(["train", "--preset", "cpu-fast", "--model.hidden_size", "16", "--model.depth", "1",
                 "--out", str(out), "--data.train", str(tmp_path / "demos"), "--data.val", str(tmp_path / "demos"),
                 "--train.steps", "4", "--train.val_every", "4", "--train.warmup_steps", "1",
                 "--train.num_workers", "0", "--train.val_demos", "2"]) == 0
    config = cfg.load(out / "config.json")
    assert (config.train.batch_size, config.data.num_action_points, config.data.num_anchor_points) == (8, 128, 128)
    model = Tax3D.from_pretrained(out / "best")
    demo = synthetic_demo(0, n=300, m=200)
    frames = model._frames(demo["action_pc"], demo["anchor_pc"], model._generator(None, 0))
    assert frames["carry"]["sampled"].shape[0] == 256
    validated = [r for r in read_log(out) if "val_rmse" in r]
    assert validated and math.isfinite(validated[-1]["val_rmse"])
    assert validated[-1]["val_rmse"] == pytest.approx(
        validation.validate(model, [load_demo(f) for f in sorted((tmp_path / "demos").glob("*.npz"))[:2]],
                       config.train.val_samples, seed=config.train.seed, points="sampled")["val_rmse"], rel=1e-5)


def test_a_compiled_run_matches_an_eager_one(tmp_path, demos):
    """--train.compile runs the same maths through torch.compile's fused kernels: the same seeded run logs the same
    losses, step by step, within float32 rounding."""
    logs = {}
    for name, extra in (("eager", []), ("compiled", ["--train.compile", "True"])):
        out = tmp_path / name
        assert main(["train", *TINY, "--out", str(out), "--data.train", str(demos), "--train.steps", "4",
                     "--train.val_every", "4", *extra]) == 0
        logs[name] = [r["loss"] for r in read_log(out)]
    assert len(logs["compiled"]) == 4
    assert logs["compiled"] == pytest.approx(logs["eager"], rel=1e-3)


def test_help_explains_every_option(capsys):
    """Every option of `tax3d train --help` shows its field's docstring beside the note on its default."""
    import dataclasses

    for section in (cfg.ModelConfig, cfg.DiffusionConfig, cfg.DataConfig, cfg.TrainConfig):
        assert set(cfg.field_docs(section)) == {f.name for f in dataclasses.fields(section)}, section
    with pytest.raises(SystemExit) as done:
        main(["train", "--help"])
    assert done.value.code == 0
    text = " ".join(capsys.readouterr().out.replace("│", " ").split())
    assert "--train.minutes" in text and "plan the run to end after this many minutes on this machine" in text
    assert "(a curve's checkpoints, to score later; 0: only best/ and last/)" in text
    assert "peak learning rate of AdamW, after the warm-up" in text and "time-limit" not in text
    assert "--model.variant" in text and "cd, cp, cd_w, cp_w, cd_nac, cp_nac, sd, sp, rd or rp" in text
    sections = (cfg.ModelConfig, cfg.DiffusionConfig, cfg.DataConfig, cfg.TrainConfig)
    own = sum("(default:" in doc for s in sections for doc in cfg.field_docs(s).values())  # gives its own default
    assert own >= 1 and text.count("(default: the preset's)") == sum(len(dataclasses.fields(s)) for s in sections) - own


def test_the_bar_shows_no_validation_where_there_is_none(tmp_path, demos, capsys):
    assert main(["train", *TINY, "--out", str(tmp_path / "run"), "--data.train", str(demos), "--train.steps", "2",
                 "--train.val_every", "2"]) == 0
    err = capsys.readouterr().err
    assert "loss=" in err and "val=" not in err


def test_generate_with_nothing_to_do_shows_no_bar(capsys):
    from tax3d.sim import generate

    assert generate._run([], generate.Args(), progress=True) == []
    assert capsys.readouterr().err == ""


def test_a_sampled_validation_measures_what_predict_returns_by_default():
    """train.val_points sampled: the network sees the farthest-point sample of its training size, as `predict` does
    by default; whole: every point. The RMSE is on the whole cloud either way."""
    from tests.conftest import tiny_model

    model = tiny_model(num_action_points=32, num_anchor_points=24)
    demo = synthetic_demo(0, n=90, m=70)  # larger clouds than the network trained on
    goal = demo["action_pc"] + demo["flow"]
    for points, max_points in (("sampled", None), ("whole", 0)):
        record = validation.validate(model, [demo], num_samples=2, seed=0, points=points)
        [samples] = model.predict_scenes([(demo["action_pc"], demo["anchor_pc"])], num_samples=2, seed=0,
                                         max_points=max_points)
        assert samples.shape == (2, 90, 3)
        assert record["val_rmse"] == pytest.approx(min(np.sqrt(((s - goal) ** 2).sum(-1).mean()) for s in samples))
    whole = validation.validate(model, [demo], num_samples=2, seed=0, points="whole")["val_rmse"]
    assert whole != pytest.approx(validation.validate(model, [demo], num_samples=2, seed=0, points="sampled")["val_rmse"])


def test_the_loop_validates_with_the_configured_points(tmp_path, monkeypatch):
    folder = tmp_path / "demos"
    folder.mkdir()
    save_demo(folder / "demo_0.npz", synthetic_demo(3))
    asked, real = [], validation.validate
    monkeypatch.setattr(learner, "validate", lambda *a, **k: asked.append(k["points"]) or real(*a, **k))
    assert main(["train", *TINY, "--out", str(tmp_path / "run"), "--data.train", str(folder), "--data.val",
                 str(folder), "--train.steps", "2", "--train.val_every", "2", "--train.val_points", "sampled"]) == 0
    assert asked == ["sampled"]
    assert cfg.load(tmp_path / "run" / "last" / "config.json").train.val_points == "sampled"
