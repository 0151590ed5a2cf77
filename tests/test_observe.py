"""The deformable as depth cameras see it (tax3d.sim.observe) and `tax3d generate --camera-out`: the visible surface,
the noise model, each observed point's goal from the surface point it came from, the same file format."""

from __future__ import annotations

import numpy as np
import pybullet
import pytest

from tax3d.data.format import load_demo
from tax3d.sim.bag import FIXED_BAG
from tax3d.sim.camera import PROJECTION, opengl_depth, render_image
from tax3d.sim.cloth import SIMPLE_CLOTH
from tax3d.sim.observe import VIEWS, CameraSpec, _render_world, camera_demo, camera_seed, first_hits, observe
from tax3d.sim.scenes import env_class

QUIET = CameraSpec(noise_base=0.0, noise_quadratic=0.0)


@pytest.fixture(scope="module")
def cloth_env():
    env = env_class("cloth")(floor=True)
    state = env.reset(SIMPLE_CLOTH, 0.4, [3.0, -5.0, 0.0])
    yield env, state
    env.close()


def test_first_hits_takes_the_nearer_triangle_and_its_barycentric_point():
    near = [[0, 0, 1], [1, 0, 1], [0, 1, 1]]
    far = [[-1, -1, 2], [2, -1, 2], [-1, 2, 2]]
    triangles = np.array([far, near], dtype=float)
    rays = np.array([[0.2, 0.3, 1.0], [0.3, -0.3, 1.0], [-0.4, -0.4, 1.0], [0.0, 0.0, -1.0]])
    t, face, weights = first_hits(np.zeros(3), rays, triangles)
    assert face[:3].tolist() == [1, 0, 0] and np.isinf(t[3])
    np.testing.assert_allclose(t[:3], [1.0, 2.0, 2.0])
    np.testing.assert_allclose(weights[0], [0.5, 0.2, 0.3])
    hit = weights[:3, :, None] * triangles[face[:3]]
    np.testing.assert_allclose(hit.sum(1), rays[:3] * t[:3, None])


def test_the_cameras_see_the_cloth_at_the_start(cloth_env):
    env, state = cloth_env
    seen = observe(env, QUIET, np.random.default_rng(0))
    assert len(seen.points) > 1000  # a 200 x 200 image of a 6 x 6 cloth one metre away, against 580 vertices
    np.testing.assert_allclose(seen.points, seen.surface, atol=1e-9)  # no noise asked for
    np.testing.assert_allclose(seen.surface[:, 1], 5.0, atol=1e-9)  # the flat cloth at the start lies in y = 5
    np.testing.assert_allclose(seen.carry(state.cloth, env.mesh.faces), seen.surface, atol=1e-9)
    # every vertex has an observed point near it: nothing hides the flat cloth from the front
    gaps = np.min(np.linalg.norm(state.cloth[:, None] - seen.points[None], axis=2), axis=1)
    assert gaps.max() < 0.3


def test_the_render_world_is_the_scene_and_agrees_with_the_rays(cloth_env):
    """The rendering world's depth buffer, at the pixels it gives the cloth, is within 1% of the rays' depth."""
    env, state = cloth_env
    client, body = _render_world(env, state.cloth, np.asarray(env.mesh.faces))
    view = pybullet.computeViewMatrixFromYawPitchRoll(state.cloth.mean(0).tolist(), 10.0, *VIEWS["front"], 0.0, 2)
    buffer, seg = render_image(client, view, PROJECTION, 200)
    depth = opengl_depth(buffer)[seg == body]
    seen = observe(env, QUIET, np.random.default_rng(0))
    eye_z = (np.c_[seen.surface, np.ones(len(seen.surface))] @ np.asarray(view).reshape(4, 4, order="F").T)[:, 2]
    camera_z = -eye_z  # OpenGL's eye frame looks along -z
    assert abs(len(depth) - len(camera_z)) < 0.05 * len(depth)
    assert abs(np.median(depth) / np.median(camera_z) - 1) < 0.01


def test_the_noise_follows_the_depth_camera_model(cloth_env):
    env, _ = cloth_env
    spec = CameraSpec()
    quiet, noisy = observe(env, QUIET, np.random.default_rng(0)), observe(env, spec, np.random.default_rng(0))
    assert len(quiet.points) == len(noisy.points)
    error = np.linalg.norm(noisy.points - quiet.points, axis=1)
    camera = np.array(pybullet.computeViewMatrixFromYawPitchRoll(
        env.cloth_vertices().mean(0).tolist(), 10.0, *VIEWS["front"], 0.0, 2)).reshape(4, 4, order="F")
    z = (np.c_[quiet.points, np.ones(len(quiet.points))] @ camera.T)[:, 2] * -1
    along_ray = error / (np.linalg.norm(quiet.points - np.linalg.inv(camera)[:3, 3], axis=1) / z)
    ratio = np.sqrt(np.mean(along_ray**2)) / np.sqrt(np.mean(spec.sigma(z) ** 2))
    assert 0.9 < ratio < 1.1  # z-depth errors of the stated standard deviation
    # one metre away the Kinect model gives about 2 mm, a fiftieth of a scene unit
    assert 0.015 < spec.sigma(np.array(10.0)) < 0.025
    twice = observe(env, spec, np.random.default_rng(0))
    np.testing.assert_array_equal(twice.points, noisy.points)


def test_a_bag_is_seen_from_one_side():
    env = env_class("bag")(floor=True)
    try:
        state = env.reset(FIXED_BAG, -0.3, [-2.0, -4.0, 0.0])
        seen = observe(env, QUIET, np.random.default_rng(0))
        both = observe(env, CameraSpec(views=("front", "back"), noise_base=0.0, noise_quadratic=0.0),
                       np.random.default_rng(0))
    finally:
        env.close()
    gaps = np.min(np.linalg.norm(state.cloth[:, None] - seen.points[None], axis=2), axis=1)
    near = (gaps < 0.2).mean()
    assert 0.2 < near < 0.8  # the front camera sees the front wall and some of the inside, not the back wall
    gaps_both = np.min(np.linalg.norm(state.cloth[:, None] - both.points[None], axis=2), axis=1)
    assert (gaps_both < 0.2).mean() > near + 0.1  # a second camera behind sees more of it


def test_camera_demo_carries_the_vertex_goals_and_grasps(cloth_env):
    env, state = cloth_env
    rng = np.random.default_rng(1)
    goal = state.cloth + rng.normal(size=state.cloth.shape)  # any per-vertex goals
    demo = {"action_pc": state.cloth.copy(), "flow": goal - state.cloth, "anchor_pc": np.ones((5, 3)),
            "rot": np.array([0, 0, 0.4]), "trans": np.array([3.0, -5.0, 0.0]), "deform_params": SIMPLE_CLOTH,
            "anchors": {7: {"pos": state.grippers[0], "vertices": [0]}, 8: {"pos": state.grippers[1], "vertices": [24]}},
            "traj_targets": np.zeros((3, 2, 3))}
    out = camera_demo(env, demo, QUIET, camera_seed("t", "s", 0))
    assert set(out) == {"action_pc", "flow", "action_seg", "anchor_pc", "rot", "trans", "deform_params", "anchors"}
    seen = observe(env, QUIET, np.random.default_rng(0))
    np.testing.assert_allclose(out["action_pc"] + out["flow"], seen.carry(goal, env.mesh.faces), atol=1e-9)
    for gripper, vertex in ((7, 0), (8, 24)):
        (row,) = out["anchors"][gripper]["vertices"]
        assert np.linalg.norm(out["action_pc"][row] - state.cloth[vertex]) < 0.15
    moved = dict(demo, action_pc=demo["action_pc"] + 0.1)
    with pytest.raises(RuntimeError, match="not the demo's action_pc"):
        camera_demo(env, moved, QUIET, camera_seed("t", "s", 0))


def test_generate_camera_out_writes_the_same_format_deterministically(generated, tmp_path):
    """Demos already in OUT get their camera demos without simulating; two runs give the same bytes' arrays."""
    from tax3d.sim.generate import Args, generate

    out, _ = generated
    stats = [generate(Args(task="hangproccloth-simple", split="unseen", num=1, out=out, camera_out=tmp_path / name),
                      progress=False) for name in ("a", "b")]
    assert [s["episodes"] for s in stats] == [0, 0] and [s["camera_written"] for s in stats] == [1, 1]
    mesh, a, b = (load_demo(p / "demo_0.npz") for p in (out, tmp_path / "a", tmp_path / "b"))
    for key in a:
        if isinstance(a[key], np.ndarray):
            np.testing.assert_array_equal(a[key], b[key])
    assert a["action_pc"].shape[0] > 1000 and a["flow"].shape == a["action_pc"].shape
    np.testing.assert_array_equal(a["anchor_pc"], mesh["anchor_pc"])
    assert a["deform_params"] == mesh["deform_params"] and a["task"] == mesh["task"]
    # each observed point's goal is where the surface around it went: within a vertex spacing of the mesh goals
    goal, mesh_goal = a["action_pc"] + a["flow"], mesh["action_pc"] + mesh["flow"]
    assert np.min(np.linalg.norm(goal[:, None] - mesh_goal[None], axis=2), axis=1).max() < 0.5
    again = generate(Args(task="hangproccloth-simple", split="unseen", num=1, out=out, camera_out=tmp_path / "a"),
                     progress=False)
    assert again["camera_written"] == 0


def test_generate_camera_out_bad_input_is_one_line(capsys, tmp_path):
    from tests.conftest import one_line_error

    one_line_error(capsys, ["generate", "--num", "1", "--out", tmp_path, "--camera-out", tmp_path],
                   "--camera-out", "expected a folder of its own")
    one_line_error(capsys, ["generate", "--num", "1", "--out", tmp_path / "m", "--camera-out", tmp_path / "c",
                            "--camera.distance", "-1"], "--camera.distance")


def test_the_policy_drives_the_grippers_to_the_goals_of_the_observed_points_nearest_the_grasps():
    from types import SimpleNamespace

    from tax3d.policies.goal import GoalPolicy

    cloth = np.array([[0.0, 0, 0], [1, 0, 0], [0, 0, 1], [1, 0, 1]])
    env = SimpleNamespace(anchor_points=lambda: np.zeros((3, 3)), mesh=SimpleNamespace(grip_vertices=lambda: (0, 3)))
    seen = np.array([[0.5, 0, 0.5], [0.98, 0.01, 1.02], [0.3, 0, 0], [0.02, 0, -0.01], [1, 0, 0]])

    class Shift:
        def predict(self, action, anchor, num_samples=1, **_):
            return np.repeat((action + [0.0, -2.0, 0.0])[None], num_samples, axis=0)

    policy = GoalPolicy(Shift(), offset=(0, 0, 0.5), observe=lambda _: seen)(env, SimpleNamespace(cloth=cloth))
    assert policy.grip == [3, 1] and policy.first_cloud is seen
    np.testing.assert_allclose(policy.targets(cloth), seen[[3, 1]] + [0.0, -2.0, 0.5])


def test_eval_scores_camera_demos_with_the_simulators_success_check(generated, tmp_path):
    """The demos' own goals, executed from the camera's cloud: the grippers take the observed points nearest the
    grasped vertices, and the simulator judges the cloth."""
    from tax3d.cli.eval import Args as EvalArgs
    from tax3d.cli.eval import evaluate
    from tax3d.sim.generate import Args, generate

    out, _ = generated
    generate(Args(task="hangproccloth-simple", split="unseen", num=1, out=out, camera_out=tmp_path / "cam" / "unseen"),
             progress=False)
    camera = load_demo(tmp_path / "cam" / "unseen" / "demo_0.npz")
    done = evaluate(EvalArgs(goal="demo", observe="camera", task="hangproccloth-simple", splits="unseen",
                             data=tmp_path / "cam", workers=1, report=False, out=tmp_path / "eval"), progress=False)
    (episode,) = done["results"]
    assert episode["success"] and episode["executed_rmse"] == 0.0
    np.testing.assert_array_equal(episode["action_pc"], camera["action_pc"])
    assert sorted(episode["grip_vertices"]) == sorted(v for g in camera["anchors"].values() for v in g["vertices"])
