"""The predictor API: frames and invariances of the variants, any number of points, checkpoints, metrics, errors."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import torch

from tax3d.cli import main
from tax3d.data.format import save_demo
from tax3d.policies.fixed import MeanGoalBaseline
from tax3d.metrics import coverage_rmse, medoid, min_of_samples_rmse, precision_rmse, rmse
from tax3d.model.tax3d import CheckpointError, Tax3D

from tests.conftest import N, scene, synthetic_demo, tiny_model


@pytest.mark.parametrize("variant", ["cd", "cp", "cd_nac", "cp_nac", "rd", "rp", "sd", "sp"])
def test_translating_the_scene_translates_the_goals(variant):
    model = tiny_model(variant)
    action, anchor, _ = scene()
    shift = np.array([3.0, -2.0, 1.5])
    goals = model.predict(action, anchor, num_samples=3, seed=7)
    moved = model.predict(action + shift, anchor + shift, num_samples=3, seed=7)
    np.testing.assert_allclose(moved, goals + shift, rtol=1e-4, atol=1e-4)


@pytest.mark.parametrize("variant", ["cd_w", "cp_w"])
def test_world_frame_variants_are_not_translation_invariant(variant):
    model = tiny_model(variant)
    action, anchor, _ = scene()
    shift = np.array([3.0, -2.0, 1.5])
    goals = model.predict(action, anchor, num_samples=3, seed=7)
    moved = model.predict(action + shift, anchor + shift, num_samples=3, seed=7)
    assert np.abs(moved - (goals + shift)).max() > 0.1


def test_no_action_context_ignores_the_action_shape():
    action, anchor, _ = scene()
    mean = action.mean(0)
    reshaped = (action - mean) * [0.3, 4.0, 1.7] + mean  # another cloth shape, same mean
    cp = tiny_model("cp_nac")
    np.testing.assert_allclose(cp.predict(reshaped, anchor, seed=3), cp.predict(action, anchor, seed=3), atol=1e-5)
    # CD-NAC: the same cross-displacements, added to the new action points
    cd = tiny_model("cd_nac")
    np.testing.assert_allclose(cd.predict(reshaped, anchor, seed=3) - reshaped,
                               cd.predict(action, anchor, seed=3) - action, atol=1e-5)
    # with the action context the prediction does change
    ctx = tiny_model("cp")
    assert np.abs(ctx.predict(reshaped, anchor, seed=3) - ctx.predict(action, anchor, seed=3)).max() > 1e-3


@pytest.mark.parametrize("variant", ["cd", "sd", "rp"])
@pytest.mark.parametrize("n,m", [(16, 24), (37, 100), (5, 7)])
def test_any_number_of_points(variant, n, m):
    model = tiny_model(variant)
    action, anchor, _ = scene(n=n, m=m)
    goals = model.predict(action, anchor, num_samples=4, seed=0)
    assert goals.shape == (4, n, 3) and np.isfinite(goals).all()
    as_tensor = model.predict(torch.as_tensor(action), torch.as_tensor(anchor), num_samples=4, seed=0)
    assert isinstance(as_tensor, torch.Tensor)
    np.testing.assert_allclose(as_tensor.numpy(), goals, atol=1e-6)


def test_samples_are_one_batch_and_steps_respace():
    model = tiny_model("cd")
    calls = []
    forward = model.net.forward
    model.net.forward = lambda x, *a: calls.append(x.shape[0]) or forward(x, *a)
    action, anchor, _ = scene()
    model.predict(action, anchor, num_samples=6, seed=0)
    assert calls == [6] * 5  # one forward per denoising step, all samples together
    calls.clear()
    goals, trajectory = model.predict(action, anchor, num_samples=2, steps=3, sampler="ddim", seed=0,
                                      return_trajectory=True)
    assert len(calls) == 3 and trajectory.shape == (4, 2, N, 3)
    np.testing.assert_allclose(trajectory[-1], goals, atol=1e-6)


def test_seed_makes_predictions_repeatable():
    model = tiny_model("cd")
    action, anchor, _ = scene()
    a = model.predict(action, anchor, num_samples=3, seed=11)
    np.testing.assert_array_equal(a, model.predict(action, anchor, num_samples=3, seed=11))
    assert np.abs(a - model.predict(action, anchor, num_samples=3, seed=12)).max() > 1e-3
    assert np.abs(a[0] - a[1]).max() > 1e-3  # the samples of one call differ


def test_predict_scenes_matches_shapes():
    model = tiny_model("cp")
    scenes = [scene(i)[:2] for i in range(3)] + [scene(5, n=9)[:2]]
    goals = model.predict_scenes(scenes, num_samples=2, seed=0, batch_scenes=2)
    assert [g.shape for g in goals] == [(2, N, 3)] * 3 + [(2, 9, 3)]


@pytest.mark.parametrize("variant", ["cd", "cp_w", "sp", "rd"])
def test_save_and_load_round_trip(tmp_path, variant):
    model = tiny_model(variant)
    model.save_pretrained(tmp_path / "ckpt")
    assert sorted(p.name for p in (tmp_path / "ckpt").iterdir()) == ["config.json", "model.safetensors"]
    loaded = Tax3D.from_pretrained(tmp_path / "ckpt")
    assert loaded.config == model.config
    action, anchor, _ = scene()
    np.testing.assert_array_equal(loaded.predict(action, anchor, num_samples=2, seed=5),
                                  model.predict(action, anchor, num_samples=2, seed=5))


def test_bad_checkpoints(tmp_path):
    with pytest.raises(CheckpointError, match="no such checkpoint"):
        Tax3D.from_pretrained(tmp_path / "missing")
    tiny_model("cd").save_pretrained(tmp_path / "ckpt")
    with pytest.raises(CheckpointError, match="variant 'cd', not the requested 'cp'"):
        Tax3D.from_pretrained(tmp_path / "ckpt", variant="cp")
    data = json.loads((tmp_path / "ckpt" / "config.json").read_text())
    data["model"]["hidden_size"] = 32
    (tmp_path / "ckpt" / "config.json").write_text(json.dumps(data))
    with pytest.raises(CheckpointError, match="weights do not match"):
        Tax3D.from_pretrained(tmp_path / "ckpt")
    (tmp_path / "ckpt" / "model.safetensors").unlink()
    with pytest.raises(CheckpointError, match="model.safetensors is missing"):
        Tax3D.from_pretrained(tmp_path / "ckpt")


def test_bad_points():
    model = tiny_model("cd")
    action, anchor, _ = scene()
    with pytest.raises(Exception, match="action_points has shape"):
        model.predict(action[:, :2], anchor)
    with pytest.raises(Exception, match="anchor_points contains NaN"):
        model.predict(action, np.full_like(anchor, np.nan))


def run_cli(capsys, *argv):
    code = main(list(argv))
    captured = capsys.readouterr()
    return code, captured.err.strip()


@pytest.fixture
def checkpoint(tmp_path):
    tiny_model("cd").save_pretrained(tmp_path / "ckpt")
    folder = tmp_path / "demos"
    folder.mkdir()
    for i in range(3):
        save_demo(folder / f"demo_{i}.npz", synthetic_demo(i))
    return tmp_path / "ckpt", folder


def test_predict_command(tmp_path, capsys, checkpoint):
    ckpt, demos = checkpoint
    code = main(["predict", "--checkpoint", str(ckpt), "--demos", str(demos), "--samples", "3", "--steps", "4",
                 "--out", str(tmp_path / "p.npz"), "--baseline", str(demos),
                 "--summary", str(tmp_path / "new" / "s.json")])
    summary = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert code == 0 and summary["demos"] == 3 and summary["rmse_min_of_samples"] <= summary["rmse_mean"]
    kept = json.loads((tmp_path / "new" / "s.json").read_text())
    assert kept["command"].startswith("tax3d predict --checkpoint") and "--summary" in kept["command"]
    assert kept["date"] and "cores" in kept["machine"] and kept["checkpoint"] == str(ckpt)
    assert {k: kept[k] for k in summary} == summary and "rmse_mean_goal_baseline" in kept
    with np.load(tmp_path / "p.npz") as f:
        assert f["goals"].shape == (3, 3, N, 3) and f["rmse"].shape == (3, 3)
        assert np.isclose(f["rmse"].min(1).mean(), summary["rmse_min_of_samples"])
        medoids = [medoid(g) for g in f["goals"]]
        assert np.isclose(np.mean([e[i] for e, i in zip(f["rmse"], medoids)]), summary["rmse_medoid"])



def test_predictions_of_demos_of_different_sizes_load_without_pickle(tmp_path, capsys, checkpoint):
    """pred.npz is plain arrays: goals padded with NaN beyond each demo's points; predict says where it wrote."""
    ckpt, _ = checkpoint
    folder = tmp_path / "sizes"
    folder.mkdir()
    for i, n in enumerate((N, N + 6)):
        save_demo(folder / f"demo_{i}.npz", synthetic_demo(i, n=n))
    out = tmp_path / "p.npz"
    assert main(["predict", "--checkpoint", str(ckpt), "--demos", str(folder), "--samples", "2", "--steps", "2",
                 "--out", str(out), "--summary", str(tmp_path / "s.json")]) == 0
    err = capsys.readouterr().err
    assert f"predictions: {out}" in err and f"summary: {tmp_path / 's.json'}" in err
    with np.load(out) as f:  # allow_pickle is False by default
        goals, points = f["goals"], f["points"]
    assert goals.shape == (2, 2, N + 6, 3) and points.tolist() == [N, N + 6]
    assert np.isnan(goals[0, :, N:]).all() and np.isfinite(goals[0, :, :N]).all() and np.isfinite(goals[1]).all()

def test_the_samplers_study_scores_each_sampler_as_predict_does_alone(tmp_path, capsys, checkpoint):
    """lab.studies.samplers: the same demos and seed under each sampler, each as `tax3d predict` scores it."""
    from lab.studies import samplers

    ckpt, demos = checkpoint
    assert samplers.main(["--checkpoint", str(ckpt), "--demos", str(demos), "--samples", "2"]) == 0
    compared = json.loads(capsys.readouterr().out)["samplers"]
    assert list(compared) == ["ddpm_10", "ddim_10", "ddpm_100"]
    assert len({row["rmse_mean"] for row in compared.values()}) == 3  # three different samplers
    argv = ["predict", "--checkpoint", str(ckpt), "--demos", str(demos), "--samples", "2"]
    assert main([*argv, "--steps", "10", "--sampler", "ddim"]) == 0  # alone, the same seed
    alone = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert {k: alone[k] for k in compared["ddim_10"]} == pytest.approx(compared["ddim_10"])


def test_predict_command_bad_input(tmp_path, capsys, checkpoint):
    ckpt, demos = checkpoint
    (tmp_path / "empty").mkdir()
    bad = tmp_path / "bad"
    bad.mkdir()
    demo = synthetic_demo(0)
    demo["anchor_pc"] = np.zeros((0, 3))
    np.savez(bad / "demo_0.npz", **{k: v for k, v in demo.items() if k not in ("deform_params", "anchors")})
    minimal = tmp_path / "minimal"
    minimal.mkdir()
    np.savez(minimal / "demo_0.npz", **{k: v for k, v in demo.items() if k in ("action_pc", "anchor_pc")})
    incomplete = tmp_path / "incomplete"
    incomplete.mkdir()
    (incomplete / "config.json").write_text((ckpt / "config.json").read_text())
    cases = [
        (["--checkpoint", str(tmp_path / "nope"), "--demos", str(demos)], "no such checkpoint"),
        (["--checkpoint", str(incomplete), "--demos", str(demos)], "model.safetensors is missing"),
        (["--checkpoint", str(ckpt), "--demos", str(demos), "--variant", "cp"], "variant 'cd'"),
        (["--checkpoint", str(ckpt), "--demos", str(tmp_path / "empty")], "no demo_N.npz files"),
        (["--checkpoint", str(ckpt), "--demos", str(bad)], "anchor_pc has shape (0, 3)"),
        (["--checkpoint", str(ckpt), "--demos", str(minimal)], "missing keys ['flow']"),
        (["--checkpoint", str(ckpt), "--demos", str(demos), "--steps", "101"], "--steps 101"),
        (["--checkpoint", str(ckpt), "--demos", str(demos), "--summary", str(demos)], "--summary"),
        (["--checkpoint", str(ckpt), "--demos", str(demos), "--out", str(demos / "demo_0.npz" / "p.npz")], "--out"),
    ]
    for argv, message in cases:
        code, err = run_cli(capsys, "predict", *argv)
        assert code == 2, argv
        assert message in err and len(err.splitlines()) == 1, err
    assert sorted(p.name for p in demos.iterdir()) == [f"demo_{i}.npz" for i in range(3)]


def test_metrics():
    goal = np.zeros((5, 3))
    pred = np.stack([np.full((5, 3), v) for v in (1.0, 2.0)])  # two samples, errors sqrt(3) and 2 sqrt(3)
    np.testing.assert_allclose(rmse(pred, goal), [np.sqrt(3), 2 * np.sqrt(3)])
    assert rmse(torch.as_tensor(pred), torch.as_tensor(goal)).shape == (2,)
    assert np.isclose(min_of_samples_rmse(pred, goal), np.sqrt(3))
    batch = np.stack([pred, pred + 1.0])  # (D = 2, K = 2, N, 3)
    np.testing.assert_allclose(min_of_samples_rmse(batch, np.zeros((2, 5, 3))), [np.sqrt(3), 2 * np.sqrt(3)])
    goals = np.stack([np.zeros((5, 3)), np.full((5, 3), 3.0)])  # two modes
    # coverage: mode 0 -> best sample 1.0 (sqrt 3); mode 3 -> best sample 2.0 (sqrt 3)
    assert np.isclose(coverage_rmse(pred, goals), np.sqrt(3))
    # precision: sample 1.0 -> mode 0 (sqrt 3); sample 2.0 -> mode 3 (sqrt 3)
    assert np.isclose(precision_rmse(pred, goals), np.sqrt(3))
    assert np.isclose(precision_rmse(pred[:1], goals), np.sqrt(3))
    assert np.isclose(coverage_rmse(pred[:1], goals), (np.sqrt(3) + 2 * np.sqrt(3)) / 2)


def test_mean_goal_baseline():
    demos = [synthetic_demo(i) for i in range(4)]
    baseline = MeanGoalBaseline.fit(demos)
    d = demos[0]
    shifted = baseline.predict(d["action_pc"], d["anchor_pc"] + 1.0) - baseline.predict(d["action_pc"], d["anchor_pc"])
    np.testing.assert_allclose(shifted, 1.0)
    single = MeanGoalBaseline.fit([d])
    np.testing.assert_allclose(single.predict(d["action_pc"], d["anchor_pc"]), d["action_pc"] + d["flow"])


def test_mean_goal_baseline_random_cloths():
    rng = np.random.default_rng(0)
    grid = np.stack(np.meshgrid(np.arange(5.0), np.arange(5.0), [0.0]), -1).reshape(-1, 3)
    anchor = rng.normal(size=(30, 3))
    demos = []
    for keep in (np.arange(25) != 12, np.arange(25) != 6):  # two cloths, each missing a different vertex
        start = grid[keep]
        demos.append({"action_pc": start, "anchor_pc": anchor, "flow": start * 0.5 + 1.0 - start})
    baseline = MeanGoalBaseline.fit(demos)
    assert baseline.starts is not None  # the cloths differ: nearest-point matching, not a point-by-point mean
    both = grid[(np.arange(25) != 12) & (np.arange(25) != 6)]  # a third cloth: its points are in both demos
    np.testing.assert_allclose(baseline.predict(both + 0.01, anchor + 2.0), both * 0.5 + 3.0)
    # the vertex missing from the first demo takes there its nearest neighbour's goal (0.5 lower in x or y)
    lone = baseline.predict(grid[12:13], anchor)
    assert 0.0 < np.abs(lone - (grid[12] * 0.5 + 1.0)).sum() <= 0.25 + 1e-9
    with pytest.raises(ValueError):
        MeanGoalBaseline.fit([])


@pytest.mark.parametrize("variant", ["cd", "cp"])
def test_large_clouds_run_the_network_on_a_sample_and_carry_its_displacements(variant):
    """Above max_points the network sees a farthest-point sample; every input point keeps its place in the output,
    a sampled point keeps its own predicted displacement and every other one moves by a weighted mean of those of
    its nearest sampled points, nearer ones weighing more."""
    from scipy.spatial import cKDTree

    from tax3d.model.tax3d import CARRY_NEIGHBOURS

    model = tiny_model(variant)
    action, anchor, _ = scene(0, n=200)
    goals = model.predict(action, anchor, num_samples=2, seed=4, max_points=20)
    assert goals.shape == (2, 200, 3) and np.isfinite(goals).all()
    displacement = goals[0] - action
    # the sampled points: those whose displacement no other point's mean reproduces exactly are 20 distinct ones
    frames = model._frames(action, anchor, model._generator(None, 4), max_points=20)
    sampled = frames["carry"]["sampled"].numpy()
    index = cKDTree(action).query(sampled)[1]
    assert len(set(index.tolist())) == 20
    own = displacement[index]
    distance, nearest = cKDTree(sampled).query(action, k=CARRY_NEIGHBOURS)
    weight = 1 / np.maximum(distance, 1e-9)
    weight[distance < 1e-9] = 1e9
    expected = (own[nearest] * (weight / weight.sum(1, keepdims=True))[..., None]).sum(1)
    np.testing.assert_allclose(displacement, expected, rtol=1e-4, atol=1e-3)
    # each point's displacement lies within the span of its neighbours' (a mean, not an extrapolation)
    low, high = own[nearest].min(1), own[nearest].max(1)
    assert np.all(displacement >= low - 1e-3) and np.all(displacement <= high + 1e-3)
    # no limit: the network sees every point (its training size by default)
    whole = model.predict(action, anchor, seed=4, max_points=0)
    np.testing.assert_allclose(whole, model.predict(action, anchor, seed=4, max_points=200), atol=1e-5)
    assert len(np.unique((whole[0] - action).round(3), axis=0)) > 150
    with pytest.raises(ValueError, match="max_points"):
        model.predict(action, anchor, max_points=-1)


def test_the_config_sets_the_points_predict_runs_the_network_on(tmp_path):
    """data.predict_points is predict's default max_points, kept with the weights; an explicit max_points wins."""
    from tax3d.model.tax3d import Tax3D

    model = tiny_model(num_action_points=16, predict_points=40)
    action, anchor, _ = scene(0, n=200)
    sampled = lambda m, **k: m._frames(action, anchor, m._generator(None, 4), **k)["carry"]["sampled"].shape[0]
    assert sampled(model) == 40 and sampled(model, max_points=20) == 20
    assert "carry" not in model._frames(action, anchor, model._generator(None, 4), max_points=0)
    np.testing.assert_allclose(model.predict(action, anchor, seed=4), model.predict(action, anchor, seed=4,
                                                                                    max_points=40), atol=1e-6)
    model.save_pretrained(tmp_path / "weights")
    assert sampled(Tax3D.from_pretrained(tmp_path / "weights")) == 40
    assert sampled(tiny_model(num_action_points=16)) == 16  # unset: the training size


@pytest.mark.parametrize("variant", ["sd", "sp"])
def test_scene_variants_always_see_the_scene_they_trained_on(variant):
    """SD/SP put the frame's origin at the mean of the action and anchor points together: a denser action cloud would
    move it away from where training put it, so the network always sees the training size, whatever max_points."""
    model = tiny_model(variant)
    action, anchor, _ = scene(0, n=200)
    trained = model.config.data.num_action_points
    for max_points in (None, 0, 100):
        frames = model._frames(action, anchor, model._generator(None, 4), max_points=max_points)
        assert frames["carry"]["sampled"].shape[0] == trained
        origin = torch.cat([frames["carry"]["sampled"], frames["anchor"] + frames["anchor_mean"]]).mean(0)
        np.testing.assert_allclose(frames["anchor_mean"].numpy(), origin.numpy(), atol=1e-5)
    whole = model.predict(action, anchor, seed=4, max_points=0)
    assert whole.shape == (1, 200, 3)
    np.testing.assert_allclose(whole, model.predict(action, anchor, seed=4), atol=1e-5)


def test_predict_scenes_reports_progress_once_per_denoising_step(monkeypatch):
    """The CLI's bar advances once per denoising step of every batch, so a long prediction shows it is alive."""
    import tqdm.auto

    bars = []

    class Bar:
        def __init__(self, total=None, disable=False, **kwargs):
            self.total, self.disable, self.n, self.closed = total, disable, 0, False
            bars.append(self)

        def update(self, n=1):
            self.n += n

        def close(self):
            self.closed = True

    monkeypatch.setattr(tqdm.auto, "tqdm", Bar)
    model = tiny_model("cd")
    scenes = [scene(i)[:2] for i in range(3)]
    model.predict_scenes(scenes, num_samples=2, steps=5, batch_scenes=2, progress=True)
    assert [(b.total, b.n, b.closed, b.disable) for b in bars] == [(10, 10, True, False)]  # 2 batches x 5 steps


def test_clouds_far_outside_the_training_extent_are_named(tmp_path, demos, capsys):
    """A checkpoint records the extent of its training clouds; predicting for clouds 1000 times larger or smaller
    warns, in which units the model expects them; a checkpoint without the record does not."""
    import warnings

    from tax3d.cli import main
    from tax3d.data.format import load_demo
    from tax3d.extent import FACTOR, ExtentWarning

    from tests.conftest import TINY

    out = tmp_path / "run"
    assert main(["train", *TINY, "--train.steps", "2", "--train.val_every", "2", "--data.train", str(demos),
                 "--out", str(out)]) == 0
    model = Tax3D.from_pretrained(out / "last")
    assert set(model.extent) == {"action", "anchor"}
    demo = load_demo(sorted(demos.iterdir())[0])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        model.predict(demo["action_pc"], demo["anchor_pc"], steps=2, seed=0)  # the training clouds: no word
        model.predict(demo["action_pc"] * (FACTOR * 0.9), demo["anchor_pc"], steps=2, seed=0)
    for scale in (1000.0, 0.001):
        with pytest.warns(ExtentWarning, match="times the .* of the clouds this checkpoint trained on; it expects "
                                               "clouds in its training data's units"):
            model.predict(demo["action_pc"] * scale, demo["anchor_pc"] * scale, steps=2, seed=0)
    capsys.readouterr()
    scaled = tmp_path / "scaled"
    scaled.mkdir()
    np.savez(scaled / "demo_0.npz", **{**{k: v for k, v in demo.items() if isinstance(v, np.ndarray)},
                                       "action_pc": demo["action_pc"] * 1000, "anchor_pc": demo["anchor_pc"] * 1000,
                                       "flow": demo["flow"] * 1000})
    import os
    import subprocess
    import sys

    done = subprocess.run([sys.executable, "-m", "tax3d.cli", "predict", "--checkpoint", str(out / "last"), "--demos",
                           str(scaled), "--steps", "2"], capture_output=True, text=True, timeout=300,
                          env={**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[1] / "src")})
    assert done.returncode == 0, done.stderr
    assert "tax3d predict: warning: the action cloud's extent (RMS distance from its mean) is" in done.stderr
    # a checkpoint from before the record: no warning
    config = json.loads((out / "last" / "config.json").read_text())
    del config["extent"]
    (out / "last" / "config.json").write_text(json.dumps(config))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        Tax3D.from_pretrained(out / "last").predict(demo["action_pc"] * 1000, demo["anchor_pc"], steps=2, seed=0)
