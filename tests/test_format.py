import io
import os
import pickle
import zipfile

import numpy as np
import pytest

from tax3d.data.format import DemoError, list_demos, load_demo, save_demo
from tax3d.sim.cloth import SIMPLE_CLOTH

from tests.conftest import make_demo


def test_round_trip(tmp_path):
    demo = make_demo()
    save_demo(tmp_path / "demo_0.npz", demo)
    back = load_demo(tmp_path / "demo_0.npz")
    for key in ("action_pc", "anchor_pc", "flow", "rot", "trans"):
        assert np.array_equal(back[key], demo[key])
    assert back["deform_params"] == SIMPLE_CLOTH
    assert back["anchors"][3]["vertices"] == [24]
    assert [p.name for p in tmp_path.iterdir()] == ["demo_0.npz"]  # no temporary file left


def test_list_demos_in_index_order(tmp_path):
    for i in (10, 2, 1):
        save_demo(tmp_path / f"demo_{i}.npz", make_demo())
    (tmp_path / "notes.txt").write_text("x")
    assert [p.name for p in list_demos(tmp_path)] == ["demo_1.npz", "demo_2.npz", "demo_10.npz"]
    (tmp_path / "empty").mkdir()
    with pytest.raises(DemoError, match="no demo_N.npz files"):
        list_demos(tmp_path / "empty")
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
