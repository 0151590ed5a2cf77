import io
import os
import pickle
import zipfile

import numpy as np
import pytest

from tax3d.data.format import (DemoError, grip_vertices, is_valid_demo, list_demos, load_demo, save_demo,
                               strip_trajectories)
from tax3d.sim.cloth import SIMPLE_CLOTH

from tests.conftest import make_demo


def test_round_trip(tmp_path):
    demo = make_demo()
    save_demo(tmp_path / "demo_0.npz", demo)
    back = load_demo(tmp_path / "demo_0.npz")
    for key in ("action_pc", "anchor_pc", "flow", "rot", "trans"):
        assert np.array_equal(back[key], demo[key])
    assert back["deform_params"] == SIMPLE_CLOTH
    assert back["anchors"][3]["vertices"] == [9]
    assert [p.name for p in tmp_path.iterdir()] == ["demo_0.npz"]  # no temporary file left


def test_list_demos_in_index_order(tmp_path):
    for i in (10, 2, 1):
        save_demo(tmp_path / f"demo_{i}.npz", make_demo())
    (tmp_path / "notes.txt").write_text("x")
    assert [p.name for p in list_demos(tmp_path)] == ["demo_1.npz", "demo_2.npz", "demo_10.npz"]
    (tmp_path / "empty").mkdir()
    with pytest.raises(DemoError, match="no demo_N.npz files in this folder$"):
        list_demos(tmp_path / "empty")
    for split in ("train", "unseen"):  # the parent of split folders: a hint at them
        (tmp_path / "empty" / split).mkdir()
        save_demo(tmp_path / "empty" / split / "demo_0.npz", make_demo())
    with pytest.raises(DemoError, match="its folders train, unseen hold some; expected one of them") as err:
        list_demos(tmp_path / "empty")
    assert str(tmp_path / "empty" / "train") in str(err.value)
    with pytest.raises(DemoError, match="no such demonstration folder"):
        list_demos(tmp_path / "missing")


@pytest.mark.parametrize(
    "change, words",
    [
        (lambda d: d.pop("flow"), "missing keys \\['flow'\\]"),
        (lambda d: d.update(flow=np.zeros((9, 3))), "flow has shape \\(9, 3\\); expected \\(10, 3\\)"),
        (lambda d: d.update(anchor_pc=np.zeros((0, 3)), anchor_seg=np.zeros(0)), "anchor_pc has shape"),
        (lambda d: d["action_pc"].__setitem__((0, 0), np.nan), "action_pc contains NaN"),
        (lambda d: d.update(deform_params={"w": 1.0}), "deform_params is not a dict"),
    ],
)
def test_bad_demo_files(tmp_path, change, words):
    demo = make_demo()
    change(demo)
    arrays = {}
    for key, value in demo.items():
        if isinstance(value, dict):
            holder = np.empty((), dtype=object)
            holder[()] = value
            value = holder
        arrays[key] = value
    path = tmp_path / "demo_0.npz"
    np.savez(path, **arrays)
    with pytest.raises(DemoError, match=words) as err:
        load_demo(path)
    assert str(path) in str(err.value) and "\n" not in str(err.value)


def test_restricted_unpickler_refuses_other_globals(tmp_path):
    class Evil:
        def __reduce__(self):
            return (os.system, ("echo pwned",))

    good = tmp_path / "good.npz"
    save_demo(good, make_demo())
    payload = pickle.dumps(Evil(), protocol=3)
    buf = io.BytesIO()
    np.lib.format.write_array_header_1_0(buf, {"descr": "|O", "fortran_order": False, "shape": ()})
    path = tmp_path / "demo_0.npz"
    with zipfile.ZipFile(good) as src, zipfile.ZipFile(path, "w") as dst:
        for name in src.namelist():
            data = buf.getvalue() + payload if name == "deform_params.npy" else src.read(name)
            dst.writestr(name, data)
    with pytest.raises(DemoError, match="not allowed"):
        load_demo(path)


def test_truncated_file(tmp_path):
    path = tmp_path / "demo_0.npz"
    save_demo(path, make_demo())
    path.write_bytes(path.read_bytes()[:100])
    with pytest.raises(DemoError, match="unreadable"):
        load_demo(path)


def test_a_missing_or_broken_file_is_no_valid_demo_whatever_is_required(tmp_path):
    path = tmp_path / "demo_0.npz"
    assert not is_valid_demo(path) and not is_valid_demo(path, ("rot",))
    save_demo(path, make_demo())
    assert is_valid_demo(path) and is_valid_demo(path, ("rot", "anchors")) and not is_valid_demo(path, ("no_key",))
    path.write_bytes(path.read_bytes()[:100])
    assert not is_valid_demo(path)


def test_a_demo_without_its_trajectories_is_the_same_demo(tmp_path):
    demo = make_demo()
    save_demo(tmp_path / "with.npz", {**demo, "traj_targets": np.ones((3, 2, 3), np.float32)})
    strip_trajectories(tmp_path / "with.npz", tmp_path / "without.npz")
    back = load_demo(tmp_path / "without.npz")
    assert sorted(back) == sorted(demo)
    assert all(np.array_equal(back[k], demo[k]) for k in ("action_pc", "anchor_pc", "flow", "rot", "trans"))
    assert sorted(p.name for p in tmp_path.iterdir()) == ["with.npz", "without.npz"]  # no temporary file left


def test_the_core_alone_loads_and_the_simulator_keys_are_named_where_needed(tmp_path):
    """action_pc, anchor_pc and flow are a demo; asked for a simulator key it lacks, the demo names the file and
    every simulator key missing (what evaluation in simulation reads), in one line."""
    demo = make_demo()
    path = tmp_path / "demo_0.npz"
    np.savez(path, **{k: demo[k] for k in ("action_pc", "anchor_pc", "flow")})
    back = load_demo(path)
    assert sorted(back) == ["action_pc", "anchor_pc", "flow"] and grip_vertices(back) == []
    with pytest.raises(DemoError, match=r"missing keys \['rot', 'trans', 'deform_params'\]") as err:
        back["trans"]
    assert str(path) in str(err.value) and "\n" not in str(err.value)
    with pytest.raises(KeyError):
        back["no_such_key"]


def test_write_demo_round_trip_with_goal_or_flow(tmp_path):
    from tax3d.data import write_demo

    action, anchor = np.random.default_rng(0).normal(size=(10, 3)), np.random.default_rng(1).normal(size=(7, 3))
    goal = action + [1.0, 2.0, 3.0]
    write_demo(tmp_path / "a" / "demo_0.npz", action.tolist(), anchor, goal=goal, task="mine",
               anchors={0: {"pos": goal[4], "vertices": [4]}})
    write_demo(tmp_path / "b" / "demo_0.npz", action, anchor, flow=goal - action)
    a, b = load_demo(tmp_path / "a" / "demo_0.npz"), load_demo(tmp_path / "b" / "demo_0.npz")
    assert np.allclose(a["flow"], [1.0, 2.0, 3.0]) and np.array_equal(a["flow"], b["flow"])
    assert a["task"] == "mine" and grip_vertices(a) == [4] and "task" not in b
    assert sorted(p.name for p in (tmp_path / "a").iterdir()) == ["demo_0.npz"]  # nothing temporary left


@pytest.mark.parametrize("kwargs, words", [
    (dict(), "neither goal nor flow given"),
    (dict(goal=np.zeros((10, 3)), flow=np.zeros((10, 3))), "both goal and flow given"),
    (dict(goal=np.zeros((1, 3))), r"goal has shape \(1, 3\); expected \(10, 3\)"),
    (dict(flow=np.full((10, 3), np.inf)), "flow contains NaN or infinite"),
    (dict(goal=np.zeros((10, 3)), anchor=np.zeros((5, 2))), r"anchor has shape \(5, 2\)"),
    (dict(goal=np.zeros((10, 3)), anchor=[["a", "b", "c"]]), "anchor is not an array of numbers"),
    (dict(goal=np.zeros((10, 3)), achors={}), r"unknown keys \['achors'\]"),
    (dict(goal=np.zeros((10, 3)), anchors={0: {"pos": np.zeros(3), "vertices": [10]}}), "anchors holds vertex 10"),
    (dict(goal=np.zeros((10, 3)), task=""), "task is ''"),
])
def test_write_demo_refuses_bad_input_in_one_line(tmp_path, kwargs, words):
    from tax3d.data import write_demo

    kwargs = {"anchor": np.zeros((5, 3)), **kwargs}
    path = tmp_path / "demo_0.npz"
    with pytest.raises(DemoError, match=words) as err:
        write_demo(path, np.zeros((10, 3)), **kwargs)
    assert str(path) in str(err.value) and "\n" not in str(err.value)
    assert not path.exists()


def test_data_task_agrees_or_says_custom(tmp_path):
    from tax3d.data import write_demo
    from tax3d.data.format import data_task

    points = np.zeros((4, 3))
    for name, task in (("simple", "hangproccloth-simple"), ("bag", "hangbag"), ("none", None)):
        extra = {} if task is None else {"task": task}
        for i in range(2):
            write_demo(tmp_path / name / f"demo_{i}.npz", points, points, flow=points, **extra)
    simple, bag, none = (list_demos(tmp_path / n) for n in ("simple", "bag", "none"))
    assert data_task(simple) == "hangproccloth-simple" and data_task(none) == "custom"
    assert data_task(none, given="hangbag") == "hangbag" and data_task(simple, "hangproccloth-simple")
    with pytest.raises(DemoError, match="names task 'hangproccloth-simple'.*'hangbag'; expected demonstrations of "
                                        "one task"):
        data_task(simple + bag)
    with pytest.raises(DemoError, match="'none'"):
        data_task(simple + none)
    with pytest.raises(DemoError, match="--data.task hangbag: .*demo_0.npz holds a demonstration of task "
                                        "'hangproccloth-simple'"):
        data_task(simple, given="hangbag")
