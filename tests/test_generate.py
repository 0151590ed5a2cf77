import numpy as np

from tax3d.cli import main
from tax3d.data.format import is_valid_demo, load_demo, save_demo
from tax3d.sim.cloth import SIMPLE_CLOTH
from tax3d.sim.generate import Args, generate
from tests.conftest import make_demo


def one_line_error(capsys, argv):
    code = main(argv)
    err = capsys.readouterr().err.strip()
    assert code == 2
    assert "\n" not in err and "Traceback" not in err
    return err


def test_unknown_task_and_split(capsys, tmp_path):
    err = one_line_error(capsys, ["generate", "--task", "hangcloth", "--out", str(tmp_path)])
    assert "--task" in err and "hangproccloth-simple" in err
    err = one_line_error(capsys, ["generate", "--split", "test", "--out", str(tmp_path)])
    assert "--split" in err and "unseen" in err and "val" in err


def test_first_index_names_and_seeds_the_demos():
    """--first-index 100 plans demo_100 ... with the seeds of those indices; a multimodal cloth's pair stays whole."""
    from tax3d.sim.generate import _generate_jobs

    jobs = _generate_jobs(Args(task="hangproccloth-unimodal", split="unseen", first_index=100, num=3))
    assert [j.names for j in jobs] == [["demo_100.npz"], ["demo_101.npz"], ["demo_102.npz"]]
    assert [j.cloth_index for j in jobs] == [100, 101, 102]
    jobs = _generate_jobs(Args(task="hangproccloth-multimodal", split="ood", first_index=100, num=4))
    assert [j.names for j in jobs] == [["demo_100.npz", "demo_101.npz"], ["demo_102.npz", "demo_103.npz"]]
    assert [j.cloth_index for j in jobs] == [50, 51] and all(j.holes == [0, 1] for j in jobs)


def test_odd_first_index_of_a_multimodal_pair_is_refused(capsys, tmp_path):
    err = one_line_error(capsys, ["generate", "--task", "hangproccloth-multimodal", "--first-index", "101",
                                  "--out", str(tmp_path / "o")])
    assert "--first-index 101" in err and "multiple of 2" in err
    assert not (tmp_path / "o").exists()


def test_unwritable_output(capsys, tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    assert "is a file" in one_line_error(capsys, ["generate", "--num", "1", "--out", str(blocker)])
    assert "is a file; expected folders" in one_line_error(capsys, ["generate", "--num", "1", "--out", str(blocker / "sub")])


def test_bad_numbers(capsys, tmp_path):
    assert "--workers" in one_line_error(capsys, ["generate", "--workers", "0", "--out", str(tmp_path)])
    assert "--num" in one_line_error(capsys, ["generate", "--num", "-1", "--out", str(tmp_path)])


def test_replay_bad_inputs(capsys, tmp_path):
    src = tmp_path / "src"
    src.mkdir()
    assert "no demo_N.npz" in one_line_error(capsys, ["generate", "--replay", str(src), "--out", str(tmp_path / "o")])
    bad = make_demo()
    bad["deform_params"] = {**SIMPLE_CLOTH, "holes": [{"x0": 20, "x1": 30, "y0": 9, "y1": 13}]}
    save_demo(src / "demo_0.npz", bad)
    err = one_line_error(capsys, ["generate", "--replay", str(src), "--out", str(tmp_path / "o")])
    assert "demo_0.npz" in err and "outside the cloth" in err
    arrays = {k: v for k, v in make_demo().items() if k not in ("flow", "deform_params", "anchors")}
    np.savez(src / "demo_0.npz", **arrays)
    err = one_line_error(capsys, ["generate", "--replay", str(src), "--out", str(tmp_path / "o")])
    assert "missing keys" in err and "flow" in err
    assert not (tmp_path / "o").exists() or not any((tmp_path / "o").iterdir())


def test_generated_demo_is_valid_and_complete(generated):
    out, stats = generated
    assert stats["written"] == 1 and stats["failed"] == []
    demo = load_demo(out / "demo_0.npz")
    assert demo["action_pc"].shape == (580, 3) and demo["flow"].shape == (580, 3)
    assert demo["deform_params"]["holes"] == SIMPLE_CLOTH["holes"] and demo["task"] == "hangproccloth-simple"
    # initial cloth: vertex 0 top-left at (-3, 5, 11), vertex 24 top-right at (3, 5, 11)
    assert np.allclose(demo["action_pc"][0], [-3, 5, 11], atol=1e-3)
    assert np.allclose(demo["action_pc"][24], [3, 5, 11], atol=1e-3)
    assert sorted(v["vertices"][0] for v in demo["anchors"].values()) == [0, 24]
    assert len(demo["anchor_pc"]) == 1301  # the render with a floor, as the official unseen split
    goal = demo["action_pc"] + demo["flow"]
    assert np.linalg.norm(goal.mean(0) - demo["action_pc"].mean(0)) > 1.0  # the cloth moved to the hanger


def test_rerun_skips_valid_files_and_redoes_broken_ones(generated):
    out, _ = generated
    again = generate(Args(task="hangproccloth-simple", split="unseen", num=1, out=out), progress=False)
    assert again["skipped"] == 1 and again["episodes"] == 0
    path = out / "demo_0.npz"
    before = load_demo(path)
    path.write_bytes(path.read_bytes()[:200])  # a file cut short, as by a kill outside the atomic rename
    (out / ".demo_0.xyz.npz.tmp").write_bytes(b"partial")
    redo = generate(Args(task="hangproccloth-simple", split="unseen", num=1, out=out), progress=False)
    assert redo["skipped"] == 0 and redo["written"] == 1 and is_valid_demo(path)
    assert np.allclose(load_demo(path)["action_pc"], before["action_pc"])


def test_short_episode_with_trajectory_and_explosion(monkeypatch):
    from tax3d.sim.env import HangClothEnv
    from tax3d.sim.episode import episode_to_demo, expert_policy, run_episode

    with HangClothEnv() as env:
        ep = run_episode(env, SIMPLE_CLOTH, 0.3, [2.0, -4.0, 0.0], expert_policy(), steps=15, trajectory=True)
        assert not ep.exploded
        traj = episode_to_demo(ep)
        assert traj["traj_gripper_pos"].shape == (15, 2, 3) and traj["traj_targets"].shape == (15, 2, 3)
        assert traj["traj_action_pc"].shape == (15, 512, 3) and traj["traj_anchor_pc"].shape == (512, 3)
        assert np.all(np.diff(traj["traj_gripper_pos"][:, 0, 1]) < 0.05)  # grippers head towards the hanger (-y)

        real = env.cloth_vertices
        calls = {"n": 0}

        def blow_up():
            calls["n"] += 1
            v = real()
            return v * 1e3 if calls["n"] > 5 else v

        monkeypatch.setattr(env, "cloth_vertices", blow_up)
        ep = run_episode(env, SIMPLE_CLOTH, 0.3, [2.0, -4.0, 0.0], expert_policy(), steps=15)
        assert ep.exploded and not ep.success and ep.goal_pc is None


def test_each_reset_loads_its_own_cloth():
    from tax3d.sim.cloth import DOUBLE_HOLE_CLOTH, build_cloth
    from tax3d.sim.env import HangClothEnv

    with HangClothEnv() as env:
        for params in (SIMPLE_CLOTH, DOUBLE_HOLE_CLOTH, {**SIMPLE_CLOTH, "w": 0.8, "h": 1.2}):
            state = env.reset(params, 0.0, [0.0, 0.0, 0.0])
            assert len(state.cloth) == build_cloth(params).num_vertices
            extent = state.cloth.max(0) - state.cloth.min(0)  # rows span 6 w in z, columns 6 h in x
            assert np.allclose(extent[[0, 2]], [6 * params["h"], 6 * params["w"]], atol=1e-3)


def test_a_reset_leaves_no_temporary_folder_behind(monkeypatch, tmp_path):
    """A pool worker ends without finalizers, so the mesh file's folder must be gone once the mesh is loaded."""
    import tempfile

    from tax3d.sim.bag import FIXED_BAG
    from tax3d.sim.bag_env import HangBagEnv
    from tax3d.sim.env import HangClothEnv

    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    with HangClothEnv() as cloth, HangBagEnv() as bag:
        cloth.reset(SIMPLE_CLOTH, 0.0, [0.0, 0.0, 0.0])
        bag.reset(FIXED_BAG, 0.0, [0.0, 0.0, 0.0])
        assert list(tmp_path.iterdir()) == []
