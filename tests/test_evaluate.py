"""The evaluation harness: a real one-episode rollout with a tiny model, worker failures, bad inputs."""

import json
import os

import numpy as np
import pytest
import torch

from tax3d import config as cfg
from tax3d.cli import main
from tax3d.cli.eval import Args, evaluate, plan
from tax3d.eval.jobs import EvalJob
from tax3d.eval.runner import run_jobs
from tax3d.eval.summary import format_table, summarise
from tax3d.policies.goal import Sampling
from tax3d.model.tax3d import Tax3D
from tax3d.sim.cloth import SIMPLE_CLOTH

from tests.conftest import one_line_error


def tiny_checkpoint(path, variant="cd", prediction="epsilon", **data):
    data.setdefault("task", "hangproccloth-simple")
    torch.manual_seed(0)
    config = cfg.validate(cfg.Config(
        model=cfg.ModelConfig(variant=variant, hidden_size=16, depth=1, num_heads=2),
        diffusion=cfg.DiffusionConfig(num_timesteps=100, sample_steps=5, prediction=prediction),
        data=cfg.DataConfig(num_action_points=64, num_anchor_points=64, **data),
    ))
    Tax3D(config).save_pretrained(path)
    return path


@pytest.fixture(scope="module")
def checkpoint(tmp_path_factory):
    # An untrained network outputs zeros (its output layer starts at zero); predicting x_0 (the cpu preset's), every
    # step's estimate of the cross-displacement is zero, so the goal is the cloth moved to the anchor and the rollout
    # runs its full length (predicting the noise, zero noise would denoise to large values instead).
    return tiny_checkpoint(tmp_path_factory.mktemp("ckpt"), prediction="sample")


def test_one_episode_rollout_and_report(checkpoint, tmp_path):
    out = evaluate(Args(checkpoint=checkpoint, splits="unseen", episodes=1, workers=1, samples=2, out=tmp_path),
                   progress=False)
    (episode,) = out["results"]
    assert isinstance(episode["success"], bool) and not episode.get("error")
    assert episode["pred_goal"].shape == (2, 580, 3)  # the full action cloud, two samples
    assert episode["released_pc"].shape == (580, 3) and episode["predict_seconds"] > 0
    assert episode["denoising"].shape == (6, 580, 3)  # noise, then 5 denoising steps
    summary = json.loads((tmp_path / "results.json").read_text())["summary"]
    assert summary["splits"]["unseen"]["episodes"] == 1 and summary["variant"] == "cd"
    assert summary["splits"]["unseen"]["rmse"] is None  # fresh poses carry no ground-truth goal
    from tax3d.checkpoint import sha256

    assert summary["weights_sha256"] == sha256(checkpoint / "model.safetensors")  # the weights it scored
    low, high = summary["splits"]["unseen"]["success_ci95"]
    assert 0.0 <= low <= summary["splits"]["unseen"]["success_rate"] <= high <= 1.0 and high - low > 0.5
    assert (tmp_path / "report.html").exists()
    assert "Success rate" in format_table(summary["splits"])
    from lab.results import kept

    assert kept.load(tmp_path / "summary.json", ("eval",)) == summary  # the kept JSON: the summary alone


def die(job):
    if job.name == "episode_1":
        os._exit(3)
    return {"split": job.split, "name": job.name, "success": True, "exploded": False, "rmse": 0.5, "min_rmse": 0.5,
            "predict_seconds": 0.1, "sim_seconds": 1.0, "checks": {}, "action_pc": None, "anchor_pc": None,
            "pred_goal": None, "true_goal": None, "released_pc": None, "grip_vertices": [], "denoising": None,
            "cloth_key": job.name}


def raises(job):
    raise RuntimeError("simulated failure")


def test_dead_worker_and_raising_episode_are_marked_failed():
    jobs = [EvalJob("unseen", f"episode_{i}", SIMPLE_CLOTH, 0.0, [0, 0, 0], True, "none") for i in range(3)]
    results = run_jobs(jobs, workers=2, progress=False, fn=die)
    assert [r["name"] for r in results] == ["episode_0", "episode_1", "episode_2"]
    dead = [r for r in results if r.get("error")]
    assert dead and all("died" in r["error"] and not r["success"] for r in dead)
    results = run_jobs(jobs[:1], workers=1, progress=False, fn=raises)
    assert results[0]["error"] == "RuntimeError: simulated failure"
    table = summarise(results, ["unseen"])
    assert table["unseen"]["success_rate"] == 0.0 and table["unseen"]["failed_runs"] == 1


def test_coverage_and_precision_over_a_clothes_goals():
    goal_a, goal_b = np.zeros((4, 3)), np.ones((4, 3))
    rows = [
        {"split": "unseen", "success": True, "exploded": False, "rmse": 0.0, "predict_seconds": 0, "sim_seconds": 0,
         "cloth_key": "c0", "true_goal": goal, "pred_goal": np.stack([goal_a, goal_a + 0.1])}
        for goal in (goal_a, goal_b)
    ]
    table = summarise(rows, ["unseen"])["unseen"]
    # coverage: goal_a is hit exactly, goal_b at best from goal_a + 0.1 (distance sqrt(3) * 0.9)
    assert table["coverage_rmse"] == pytest.approx((0.0 + np.sqrt(3) * 0.9) / 2)
    # precision: every sample is closest to goal_a: samples 0, 0.1 sqrt(3), repeated for both rows
    assert table["precision_rmse"] == pytest.approx(np.sqrt(3) * 0.1 / 2)



def test_bad_inputs(capsys, checkpoint, tmp_path):
    assert "no such checkpoint" in one_line_error(capsys, ["eval", "--checkpoint", str(tmp_path / "nope")])
    (tmp_path / "empty_ckpt").mkdir()
    assert "incomplete checkpoint" in one_line_error(capsys, ["eval", "--checkpoint", str(tmp_path / "empty_ckpt")])
    err = one_line_error(capsys, ["eval", "--checkpoint", str(checkpoint), "--episodes", "0", "--out", str(tmp_path)])
    assert "--episodes 0" in err
    data = tmp_path / "data"
    (data / "unseen").mkdir(parents=True)
    err = one_line_error(capsys, ["eval", "--checkpoint", str(checkpoint), "--data", str(data), "--splits", "unseen",
                                  "--out", str(tmp_path)])
    assert "no demo_N.npz" in err
    other = tiny_checkpoint(tmp_path / "other", task="hangproccloth-multimodal")
    err = one_line_error(capsys, ["eval", "--checkpoint", str(other), "--task", "hangproccloth-simple",
                                  "--out", str(tmp_path)])
    assert "trained for task 'hangproccloth-multimodal'" in err
    for task, says in (("", "trained on no recorded task"), ("custom", "trained on custom demonstrations")):
        unknown = tiny_checkpoint(tmp_path / f"unknown{task}", task=task)
        one_line_error(capsys, ["eval", "--checkpoint", unknown, "--task", "hangbag", "--out", tmp_path],
                       str(unknown), says, "'hangbag'", "--data.task hangbag")
    one_line_error(capsys, ["eval", "--checkpoint", checkpoint, "--splits", "unseen,ood,unseen", "--out",
                            tmp_path / "twice"], "--splits 'unseen,ood,unseen': unseen is named twice")
    assert not (tmp_path / "twice").exists()


def test_policy_offset_reaches_the_jobs_and_the_gripper_targets(checkpoint):
    from tax3d.policies.goal import GoalPolicy

    default = plan(Args(checkpoint=checkpoint, task="hangbag", splits="unseen", episodes=1))
    chosen = plan(Args(checkpoint=checkpoint, task="hangbag", splits="unseen", episodes=1,
                            policy_offset=(0.0, 0.0, 0.5)))
    assert default[0].offset is None and chosen[0].offset == (0.0, 0.0, 0.5)

    class Fixed:
        def predict(self, cloth, anchor, num_samples=1, steps=None, sampler=None, seed=None, max_points=None):
            return np.asarray(cloth, dtype=float)[None] + 1.0

    class Env:
        mesh = type("Mesh", (), {"grip_vertices": staticmethod(lambda: (0, 2))})()

        def anchor_points(self):
            return np.zeros((4, 3))

    state = type("State", (), {"cloth": np.arange(9.0).reshape(3, 3)})()
    policy = GoalPolicy(Fixed(), offset=(0.0, -0.5, 1.0))(Env(), state)
    assert np.allclose(policy.targets(state.cloth), state.cloth[[0, 2]] + 1.0 + [0.0, -0.5, 1.0])


def test_medoid_is_the_sample_nearest_the_others():
    from tax3d.metrics import medoid

    rng = np.random.default_rng(0)
    centre = rng.normal(size=(20, 3))
    samples = np.stack([centre + 2.0, centre - 1.5, centre + 0.1, centre + [3.0, 0.0, 0.0]])
    assert medoid(samples) == 2
    assert medoid(samples[[3, 2, 1, 0]]) == 1
    assert medoid(samples[:1]) == 0


def test_the_policy_executes_the_first_sample():
    from tax3d.policies.goal import GoalPolicy

    shifts = np.array([5.0, 1.0, 0.0, -4.0, 3.0])[:, None, None]

    class Spread:
        def predict(self, cloth, anchor, num_samples=1, steps=None, sampler=None, seed=None, max_points=None):
            return np.asarray(cloth, dtype=float)[None] + shifts[:num_samples]

    class Env:
        mesh = type("Mesh", (), {"grip_vertices": staticmethod(lambda: (0, 2))})()

        def anchor_points(self):
            return np.zeros((4, 3))

    state = type("State", (), {"cloth": np.arange(9.0).reshape(3, 3)})()
    first = GoalPolicy(Spread(), Sampling(samples=5))(Env(), state)
    assert first.first_prediction.shape == (5, 3, 3)
    assert np.allclose(first.targets(state.cloth), state.cloth[[0, 2]] + 5.0)


def _policy_goals(model, cloth, anchor, **options):
    """The goals GoalPolicy predicts with these options in a stand-in scene, and what the model predicts with them."""
    from tax3d.policies.goal import GoalPolicy

    class Env:
        mesh = type("Mesh", (), {"grip_vertices": staticmethod(lambda: (0, 2))})()

        def anchor_points(self):
            return anchor

    state = type("State", (), {"cloth": cloth})()
    policy = GoalPolicy(model, Sampling(samples=2, steps=3, seed=5, **options))(Env(), state)
    return policy.first_prediction, model.predict(cloth, anchor, num_samples=2, steps=3, seed=5, **options)


def test_sampler_reaches_the_jobs_and_the_model(checkpoint, tmp_path):
    from tax3d.policies.load import load_model

    assert plan(Args(checkpoint=checkpoint, splits="unseen", episodes=1))[0].sampling.sampler is None
    assert plan(Args(checkpoint=checkpoint, splits="unseen", episodes=1, sampler="ddim"))[0].sampling.sampler == "ddim"
    # predicting the noise, where the untrained network's zero output leaves the samplers' noise in the goals
    model = load_model(tiny_checkpoint(tmp_path / "epsilon"))
    rng = np.random.default_rng(0)
    cloth, anchor = rng.normal(size=(40, 3)), rng.normal(size=(30, 3))
    goals = {}
    for sampler in ("ddpm", "ddim"):
        goals[sampler], expected = _policy_goals(model, cloth, anchor, sampler=sampler)
        assert np.allclose(goals[sampler], expected)
    assert not np.allclose(goals["ddpm"], goals["ddim"])


def test_max_points_reaches_the_jobs_and_the_model(checkpoint, tmp_path):
    from tax3d.policies.load import load_model

    assert plan(Args(checkpoint=checkpoint, splits="unseen", episodes=1))[0].sampling.max_points is None
    assert plan(Args(checkpoint=checkpoint, splits="unseen", episodes=1, max_points=0))[0].sampling.max_points == 0
    model = load_model(tiny_checkpoint(tmp_path / "epsilon"))  # trained on 64 action points
    rng = np.random.default_rng(0)
    cloth, anchor = rng.normal(size=(100, 3)), rng.normal(size=(30, 3))
    goals = {}
    for points in (None, 0):
        goals[points], expected = _policy_goals(model, cloth, anchor, max_points=points)
        assert goals[points].shape == (2, 100, 3) and np.allclose(goals[points], expected)
    assert not np.allclose(goals[None], goals[0])


def test_goal_options_need_the_demos_and_no_checkpoint(capsys, checkpoint, tmp_path):
    data = tmp_path / "data"
    (data / "unseen").mkdir(parents=True)
    one_line_error(capsys, ["eval", "--out", tmp_path / "a"], "--checkpoint", "missing")
    one_line_error(capsys, ["eval", "--goal", "demo", "--out", tmp_path / "a"], "--goal demo", "needs --data")
    one_line_error(capsys, ["eval", "--goal", "demo", "--checkpoint", checkpoint, "--data", data, "--out",
                            tmp_path / "a"], "not used with --goal demo")
    one_line_error(capsys, ["eval", "--goal", "demo", "--data", data, "--splits", "unseen,ood", "--out",
                            tmp_path / "a"], "no demo folder for ood")
    one_line_error(capsys, ["eval", "--goal", "mean", "--data", data, "--splits", "unseen", "--out", tmp_path / "a"],
                   "no train folder")
    assert not (tmp_path / "a").exists()  # nothing written


@pytest.mark.slow
def test_the_demo_goal_and_the_mean_goal_run_through_the_policy(generated, tmp_path, capsys):
    """--goal demo executes each demo's own goal (RMSE 0: the policy's ceiling); --goal mean the training set's mean
    goal in the anchor frame (the floor), here one training demo, so the same goal again."""
    import shutil

    folder, _ = generated
    data = tmp_path / "data"
    for split in ("train", "unseen"):
        shutil.copytree(folder, data / split)
    for goal in ("demo", "mean"):
        out = tmp_path / goal
        assert main(["eval", "--goal", goal, "--task", "hangproccloth-simple", "--data", str(data),
                     "--splits", "unseen", "--workers", "1", "--no-report", "--out", str(out)]) == 0
        summary = json.loads((out / "results.json").read_text())["summary"]
        assert summary["variant"] == f"{goal}-goal" and summary["checkpoint"] is None and summary["goal"] == goal
        split = summary["splits"]["unseen"]
        assert split["episodes"] == 1 and split["rmse"] < 1e-6 and split["executed_rmse"] < 1e-6
        assert split["executed_grip_error"] < 1e-6  # the grasped vertices' own goals, exactly
        assert split["success_rate"] == 1.0  # the expert's own goal hangs the fixed cloth
    assert "the demos in" in capsys.readouterr().out


def test_first_index_picks_the_test_episodes_of_a_demo_folder(tmp_path):
    """--first-index 100 --episodes 2 scores demo_100 and demo_101 of the folder, never demo_0 ...; a folder with no
    demo from that index on is a one-line error."""
    from tax3d.data.format import save_demo
    from tax3d.errors import UsageError

    from tests.conftest import make_demo

    (tmp_path / "unseen").mkdir()
    for i in (0, 1, 100, 101, 102):
        save_demo(tmp_path / "unseen" / f"demo_{i}.npz", make_demo())
    names = lambda **kw: [j.name for j in plan(Args(checkpoint=tmp_path, data=tmp_path, splits="unseen", **kw))]
    assert names(first_index=100, episodes=2) == ["demo_100", "demo_101"]
    assert names(first_index=100) == ["demo_100", "demo_101", "demo_102"]
    assert names(episodes=2) == ["demo_0", "demo_1"]
    jobs = plan(Args(checkpoint=tmp_path, data=tmp_path, splits="unseen", first_index=100, seed=7))
    assert [j.sampling.seed for j in jobs] == [107, 108, 109]  # the seed follows the demo's index, not its position
    with pytest.raises(UsageError, match="no demo files from demo_200.npz on"):
        plan(Args(checkpoint=tmp_path, data=tmp_path, splits="unseen", first_index=200))


def test_success_interval_is_wilsons():
    from tax3d.metrics import success_interval

    low, high = success_interval(35, 40)
    assert low == pytest.approx(0.7389, abs=1e-4) and high == pytest.approx(0.9454, abs=1e-4)
    assert success_interval(40, 40)[1] == 1.0 and success_interval(0, 40)[0] == 0.0


def test_evaluation_of_demos_without_the_simulator_keys_names_the_file_and_the_keys(capsys, tmp_path):
    """Own demonstrations (the core keys alone) train and predict, but cannot be replayed in the simulator: eval
    --data says which file lacks which keys, in one line, before any episode runs."""
    from tax3d.data import write_demo

    points = np.random.default_rng(0).normal(size=(8, 3))
    write_demo(tmp_path / "data" / "unseen" / "demo_0.npz", points, points, flow=np.zeros((8, 3)))
    one_line_error(capsys, ["eval", "--goal", "demo", "--data", tmp_path / "data", "--splits", "unseen",
                            "--out", tmp_path / "e"],
                   str(tmp_path / "data" / "unseen" / "demo_0.npz"), "missing keys ['rot', 'trans', 'deform_params']")
    assert not (tmp_path / "e").exists()


@pytest.mark.slow
def test_an_interrupted_evaluation_resumes_with_the_missing_episodes(generated, tmp_path, monkeypatch):
    """Each finished episode is kept as it finishes; the same command again runs only the others, and scores what an
    uninterrupted run scores."""
    import shutil

    from tax3d.eval import episodes, runner

    folder, _ = generated
    data = tmp_path / "data"
    (data / "unseen").mkdir(parents=True)
    for i in range(2):
        shutil.copy(next(folder.glob("demo_*.npz")), data / "unseen" / f"demo_{i}.npz")
    command = ["eval", "--goal", "demo", "--task", "hangproccloth-simple", "--data", str(data), "--splits", "unseen",
               "--workers", "1", "--no-report"]
    assert main([*command, "--out", str(tmp_path / "whole")]) == 0

    keep = episodes.Episodes.keep

    def keep_then_interrupt(self, job, result):
        keep(self, job, result)
        raise KeyboardInterrupt

    monkeypatch.setattr(episodes.Episodes, "keep", keep_then_interrupt)
    out = tmp_path / "resumed"
    assert main([*command, "--out", str(out)]) == 130
    assert [p.name for p in (out / "episodes").iterdir()] == ["unseen-demo_0.pkl"]
    monkeypatch.setattr(episodes.Episodes, "keep", keep)
    run = []
    run_episode = runner.run_episode
    monkeypatch.setattr(runner, "run_episode", lambda *a, **k: run.append(1) or run_episode(*a, **k))
    assert main([*command, "--out", str(out)]) == 0
    assert len(run) == 1 and not (out / "episodes").exists()

    def scores(path):
        results = json.loads((path / "results.json").read_text())
        timed = ("predict_seconds", "sim_seconds")
        return ([{k: v for k, v in e.items() if k not in timed} for e in results["episodes"]],
                {k: v for k, v in results["summary"]["splits"]["unseen"].items() if k not in timed})

    assert scores(out) == scores(tmp_path / "whole")


def test_warnings_of_the_episodes_are_said_once_by_the_command(monkeypatch):
    """Episodes run in workers without the command's warning format: each comes back with its warnings, which the
    command says once, with how many episodes raised them; the kept results do not carry them."""
    import types
    import warnings

    from tax3d.eval import runner
    from tax3d.extent import ExtentWarning

    def episode(job):
        warnings.warn("the action cloud is far off", ExtentWarning)
        return {"split": job.split, "name": job.name}

    monkeypatch.setattr(runner, "episode", episode)
    jobs = [types.SimpleNamespace(split="val", name=f"demo_{i}") for i in range(3)]
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("default")
        results = runner.run_jobs(jobs, 1, progress=False)
    assert [str(w.message) for w in caught] == ["the action cloud is far off (in 3 of 3 episodes)"]
    assert results == [{"split": "val", "name": f"demo_{i}"} for i in range(3)]
