"""The demonstration file: the official npz layout, validated, loaded safely, written atomically.

Training and prediction read three arrays, all in one world frame: `action_pc` (N, 3), the deformable's points;
`anchor_pc` (M, 3), the anchor's; `flow` (N, 3), where each action point goes (goal = action_pc + flow). Every
other key is optional and read only where it means something: `rot`, `trans` and `deform_params` (the anchor pose
and the cloth or bag) by evaluation in simulation, `anchors` (gripper id -> {pos, vertices}) for the grasped
vertices, `task` for the task the demonstrations come from (docs/own-data.md).
"""

from __future__ import annotations

import io
import json
import os
import pickle
import re
import zipfile
from pathlib import Path

import numpy as np

from tax3d.atomic import atomic_write
from tax3d.errors import UsageError

CORE_KEYS = ("action_pc", "anchor_pc", "flow")
SIM_KEYS = ("rot", "trans", "deform_params")  # what evaluation in simulation replays: the anchor pose, the cloth
OBJECT_KEYS = ("deform_params", "anchors")
OPTIONAL_KEYS = ("action_seg", "anchor_seg", "speed_factor", "rot", "trans", "deform_params", "anchors", "task")
CUSTOM_TASK = "custom"  # the task recorded for demonstrations that name none
# deform_params of a HangBag demo: the procedural bag's sizes (tax3d.sim.bag.BagParams).
BAG_KEYS = frozenset({"width", "depth", "height", "handle_gap", "handle_rise", "strap", "spacing", "handle_segments"})
# Coordinates of a scene are tens of units; values beyond this are a broken file, and would overflow in training.
MAX_COORDINATE = 1e6
# Optional per-step trajectory arrays written by `tax3d generate --trajectories` (for the DP3 baseline).
TRAJECTORY_PREFIX = "traj_"

_DEMO_NAME = re.compile(r"^demo_(\d+)\.npz$")


class DemoError(UsageError):
    """A demonstration file that is missing, unreadable or malformed."""


class Demo(dict):
    """A loaded demonstration: a dict of its keys that knows its file. Asked for a simulator key it lacks, it raises
    a DemoError naming the file and every simulator key missing, instead of a bare KeyError."""

    path: Path = Path("<demo>")

    def __missing__(self, key):
        if key in SIM_KEYS:
            missing = [k for k in SIM_KEYS if k not in self]
            raise DemoError(f"{self.path}: missing keys {missing}; evaluation in simulation needs {list(SIM_KEYS)} "
                            f"(the anchor pose and the cloth), training and prediction only {list(CORE_KEYS)}")
        raise KeyError(key)


class _PlainUnpickler(pickle.Unpickler):
    """Admits only plain containers, numbers, strings and numpy arrays: no other global may load."""

    def find_class(self, module: str, name: str):
        if name == "_reconstruct" and module in ("numpy.core.multiarray", "numpy._core.multiarray"):
            return _reconstruct
        if name == "scalar" and module in ("numpy.core.multiarray", "numpy._core.multiarray"):
            return _scalar
        if module == "numpy" and name in ("ndarray", "dtype"):
            return getattr(np, name)
        raise pickle.UnpicklingError(f"global {module}.{name} is not allowed")


def _reconstruct(subtype, shape, dtype):
    if subtype is not np.ndarray:
        raise pickle.UnpicklingError("only plain numpy arrays are allowed")
    return np.ndarray.__new__(np.ndarray, shape, dtype)


def _scalar(dtype, data=None):
    if not isinstance(dtype, np.dtype) or dtype.hasobject:
        raise pickle.UnpicklingError("only plain numeric scalars are allowed")
    return np.frombuffer(data, dtype=dtype)[0]


def _read_header(f):
    version = np.lib.format.read_magic(f)
    if version == (1, 0):
        return np.lib.format.read_array_header_1_0(f)
    return np.lib.format.read_array_header_2_0(f)


def _read_array(zf: zipfile.ZipFile, key: str) -> np.ndarray:
    """A plain array member, after checking that its header's size fits the bytes stored."""
    with zf.open(key + ".npy") as f:
        shape, _, dtype = _read_header(f)
        stored = zf.getinfo(key + ".npy").file_size - f.tell()
        if dtype.hasobject or int(np.prod(shape, dtype=np.float64)) * dtype.itemsize > stored:
            raise DemoError(f"{key} claims shape {shape} of {dtype} but holds {stored} bytes")
        f.seek(0)
        return np.lib.format.read_array(f, allow_pickle=False)


def _read_object(zf: zipfile.ZipFile, key: str):
    with zf.open(key + ".npy") as f:
        shape, _, dtype = _read_header(f)
        if dtype.hasobject:
            value = _PlainUnpickler(io.BytesIO(f.read())).load()
            if isinstance(value, np.ndarray) and value.shape == ():
                value = value.item()
            return value
        f.seek(0)
        return np.lib.format.read_array(f, allow_pickle=False)


def _to_plain(value):
    """Numpy scalars and arrays inside the pickled dicts become plain Python values."""
    if isinstance(value, dict):
        return {(_to_plain(k)): _to_plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_to_plain(v) for v in value]
    if isinstance(value, np.ndarray):
        return value.astype(np.float64) if value.dtype.kind == "f" else value
    if isinstance(value, np.generic):
        return value.item()
    return value


def load_demo(path: str | os.PathLike) -> dict:
    """Load and validate one demo file; raises DemoError naming the file and the problem."""
    path = Path(path)
    if not path.is_file():
        raise DemoError(f"{path}: no such demonstration file")
    try:
        with zipfile.ZipFile(path) as zf:
            names = {n[:-4] for n in zf.namelist() if n.endswith(".npy")}
            missing = [k for k in CORE_KEYS if k not in names]
            if missing:
                raise DemoError(f"{path}: missing keys {missing}; expected at least {list(CORE_KEYS)}")
            demo = Demo()
            demo.path = path
            for key in sorted(names):
                if key in OBJECT_KEYS:
                    demo[key] = _to_plain(_read_object(zf, key))
                else:
                    demo[key] = _read_array(zf, key)
            if "task" in demo:
                demo["task"] = _task_name(demo["task"], path)
    except DemoError as err:
        raise DemoError(f"{path}: {err}" if not str(err).startswith(str(path)) else str(err)) from None
    except (RecursionError, MemoryError):
        raise DemoError(f"{path}: unreadable demonstration file (nested or sized beyond what a demo holds)") from None
    except (zipfile.BadZipFile, pickle.UnpicklingError, ValueError, OSError, EOFError) as err:
        raise DemoError(f"{path}: unreadable demonstration file ({err})") from None
    validate_demo(demo, path)
    return demo


def validate_demo(demo: dict, path: str | os.PathLike = "<demo>") -> None:
    """Shapes, finiteness and the parsed dicts of a demo; raises DemoError."""
    a, b = demo.get("action_pc"), demo.get("anchor_pc")
    if not isinstance(a, np.ndarray) or a.ndim != 2 or a.shape[1] != 3 or a.shape[0] == 0:
        raise DemoError(f"{path}: action_pc has shape {getattr(a, 'shape', None)}; expected (N, 3) with N > 0")
    if not isinstance(b, np.ndarray) or b.ndim != 2 or b.shape[1] != 3 or b.shape[0] == 0:
        raise DemoError(f"{path}: anchor_pc has shape {getattr(b, 'shape', None)}; expected (M, 3) with M > 0")
    expect = {"flow": a.shape, "action_seg": a.shape[:1], "anchor_seg": b.shape[:1], "rot": (3,), "trans": (3,)}
    for key, shape in expect.items():
        value = demo.get(key)
        if (key == "flow" or key in demo) and (not isinstance(value, np.ndarray) or value.shape != shape):
            raise DemoError(f"{path}: {key} has shape {getattr(value, 'shape', None)}; expected {shape}")
    for key in ("action_pc", "anchor_pc", "flow", "rot", "trans"):
        if key not in demo:
            continue
        if demo[key].dtype.kind not in "fiu":
            raise DemoError(f"{path}: {key} has dtype {demo[key].dtype}; expected real numbers")
        if not np.all(np.isfinite(demo[key])):
            raise DemoError(f"{path}: {key} contains NaN or infinite values")
        if np.abs(demo[key]).max(initial=0.0) > MAX_COORDINATE:
            raise DemoError(f"{path}: {key} has values beyond {MAX_COORDINATE:g}; expected scene coordinates")
    params = demo.get("deform_params")
    if "deform_params" in demo and not (isinstance(params, dict) and BAG_KEYS <= set(params)):
        _validate_cloth_dict(params, path)  # a bag's sizes are checked when it is built
    if "anchors" in demo:
        _validate_anchors(demo["anchors"], len(a), path)
    if "task" in demo and not (isinstance(demo["task"], str) and demo["task"].strip()):
        raise DemoError(f"{path}: task is {demo['task']!r}; expected the name of the task, a non-empty string")


def _validate_anchors(anchors, n: int, path) -> None:
    if not isinstance(anchors, dict) or not all(isinstance(g, dict) and "vertices" in g for g in anchors.values()):
        raise DemoError(f"{path}: anchors is not a dict of gripper id -> {{pos, vertices}}")
    rows = [v for gripper in anchors.values() for v in np.ravel(gripper["vertices"])]
    bad = [v for v in rows if not isinstance(v, (int, np.integer)) or isinstance(v, bool) or not 0 <= v < n]
    if bad:
        raise DemoError(f"{path}: anchors holds vertex {bad[0]}; expected row numbers of action_pc, 0 to {n - 1}")


def _task_name(value, path) -> str:
    if not (isinstance(value, np.ndarray) and value.shape == () and value.dtype.kind == "U"):
        raise DemoError(f"{path}: task is not a string; expected the name of the task the demo comes from")
    return str(value)


def _validate_cloth_dict(params, path) -> None:
    if not isinstance(params, dict) or not {"node_density", "w", "h", "holes"} <= set(params):
        raise DemoError(f"{path}: deform_params is not a dict with node_density, w, h and holes (a cloth) "
                        f"or {', '.join(sorted(BAG_KEYS))} (a bag)")
    if not isinstance(params["holes"], list) or not all(
        isinstance(h, dict) and {"x0", "x1", "y0", "y1"} <= set(h) for h in params["holes"]
    ):
        raise DemoError(f"{path}: deform_params.holes must be a list of {{x0, x1, y0, y1}} dicts")


def save_demo(path: str | os.PathLike, demo: dict) -> None:
    """Write a demo in the official layout, atomically (temporary file in the same folder, then rename)."""
    path = Path(path)
    missing = [k for k in CORE_KEYS if k not in demo]
    if missing:
        raise DemoError(f"{path}: missing keys {missing}; expected at least {list(CORE_KEYS)}")
    validate_demo(demo, path)
    arrays = {}
    for key, value in demo.items():
        if key in OBJECT_KEYS:
            holder = np.empty((), dtype=object)
            holder[()] = value
            arrays[key] = holder
        else:
            arrays[key] = np.asarray(value)
            if arrays[key].dtype.hasobject:
                raise DemoError(f"{path}: {key} is not an array of numbers or a string; expected one of those")
    def write(tmp: Path) -> None:
        with open(tmp, "wb") as f:  # a file object, so numpy does not append ".npz" to the temporary name
            np.savez(f, **arrays)

    atomic_write(path, write)


def strip_trajectories(src: str | os.PathLike, dst: str | os.PathLike) -> None:
    """Copy a demo without its traj_* arrays, atomically: the same demonstration, a twentieth of the size."""
    def write(tmp: Path) -> None:
        with zipfile.ZipFile(src) as zin, zipfile.ZipFile(tmp, "w", zipfile.ZIP_DEFLATED) as zout:
            for info in zin.infolist():
                if not info.filename.startswith(TRAJECTORY_PREFIX):
                    zout.writestr(info, zin.read(info))

    atomic_write(Path(dst), write)


def write_demo(path: str | os.PathLike, action, anchor, goal=None, flow=None, **extra) -> Path:
    """Write one demonstration, validated and atomically: world-frame `action` (N, 3) points of the deformable,
    `anchor` (M, 3) points of what it is placed on, and either `goal` (N, 3), where each action point ends, or
    `flow` = goal - action. `extra` holds optional keys (OPTIONAL_KEYS: task, anchors, rot, trans, deform_params,
    ...; docs/own-data.md). Raises DemoError (a ValueError) naming the file and what is wrong."""
    path = Path(path)
    if path.suffix != ".npz":
        raise DemoError(f"{path}: expected a .npz file (training reads the demo_N.npz files of a folder)")
    if (goal is None) == (flow is None):
        raise DemoError(f"{path}: {'both goal and flow' if goal is not None else 'neither goal nor flow'} given; "
                        f"expected one of them")
    unknown = sorted(k for k in extra if k not in OPTIONAL_KEYS and not k.startswith(TRAJECTORY_PREFIX))
    if unknown:
        raise DemoError(f"{path}: unknown keys {unknown}; expected optional keys among {list(OPTIONAL_KEYS)}")
    action, anchor = _points(path, "action", action), _points(path, "anchor", anchor)
    name, target = ("goal", goal) if goal is not None else ("flow", flow)
    target = _points(path, name, target)
    if target.shape != action.shape:
        raise DemoError(f"{path}: {name} has shape {target.shape}; expected {action.shape}, a row per action point")
    flow = target - action if name == "goal" else target
    path.parent.mkdir(parents=True, exist_ok=True)
    save_demo(path, {"action_pc": action, "anchor_pc": anchor, "flow": flow, **extra})
    return path


def _points(path: Path, name: str, value) -> np.ndarray:
    try:
        points = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise DemoError(f"{path}: {name} is not an array of numbers; expected a (K, 3) array") from None
    if points.ndim != 2 or points.shape[1] != 3 or len(points) == 0:
        raise DemoError(f"{path}: {name} has shape {points.shape}; expected (K, 3) with K > 0")
    if not np.all(np.isfinite(points)):
        raise DemoError(f"{path}: {name} contains NaN or infinite values; expected finite coordinates")
    return points


def grip_vertices(demo: dict) -> list[int]:
    """The action-cloud rows the demo's grippers hold: the vertices of its `anchors` (none without them)."""
    return [int(v) for gripper in demo.get("anchors", {}).values() for v in np.ravel(gripper["vertices"])]


def read_task(path: str | os.PathLike) -> str:
    """The task a demo file names in its `task` key ("" when it names none); reads that key alone."""
    try:
        with zipfile.ZipFile(path) as zf:
            return _task_name(_read_array(zf, "task"), path) if "task.npy" in zf.namelist() else ""
    except DemoError:
        raise
    except (zipfile.BadZipFile, ValueError, OSError, EOFError) as err:
        raise DemoError(f"{path}: unreadable demonstration file ({err})") from None


def data_task(files, given: str = "", option: str = "--data.task") -> str:
    """The task of a set of demo files: the one their `task` key names, the same in every file, or CUSTOM_TASK
    where none names one. `given` (the option) wins where the files name no task, and must agree where they do."""
    named: dict[str, Path] = {}
    for path in files:
        named.setdefault(read_task(path), Path(path))
    if given:
        other = next((t for t in named if t and t != given), None)
        if other is not None:
            raise DemoError(f"{option} {given}: {named[other]} holds a demonstration of task {other!r}; expected "
                            f"demonstrations of {given!r}")
        return given
    if len(named) > 1:
        (a, first), (b, second) = list(named.items())[:2]
        raise DemoError(f"{first} names task {a or 'none'!r}, {second} {b or 'none'!r}; expected demonstrations of "
                        f"one task (or {option} naming it)")
    return next(iter(named)) or CUSTOM_TASK


def demo_index(path: str | os.PathLike) -> int | None:
    m = _DEMO_NAME.match(Path(path).name)
    return int(m.group(1)) if m else None


def list_demos(folder: str | os.PathLike) -> list[Path]:
    """The demo_N.npz files of a folder, in index order; raises DemoError for a missing or empty folder."""
    folder = Path(folder)
    if not folder.is_dir():
        raise DemoError(f"{folder}: no such demonstration folder")
    files = sorted((p for p in folder.iterdir() if demo_index(p) is not None), key=demo_index)
    if not files:
        holding = sorted(p.name for p in folder.iterdir() if p.is_dir() and next(p.glob("demo_*.npz"), None))
        if holding:
            raise DemoError(f"{folder}: no demo_N.npz files in this folder, but its folders {', '.join(holding)} "
                            f"hold some; expected one of them (such as {folder / holding[0]})")
        raise DemoError(f"{folder}: no demo_N.npz files in this folder")
    return files


def cloth_groups(folder: str | os.PathLike) -> list[list[dict]]:
    """The demos of a folder grouped by cloth and anchor pose, in index order: a multimodal cloth's demos, one per
    hole, share both (appendix C); a unimodal cloth has one."""
    groups: dict[str, list[dict]] = {}
    for path in list_demos(folder):
        d = load_demo(path)
        key = json.dumps([d["deform_params"], np.round(d["rot"], 9).tolist(), np.round(d["trans"], 9).tolist()])
        groups.setdefault(key, []).append(d)
    return list(groups.values())


def is_valid_demo(path: str | os.PathLike, require=()) -> bool:
    """Whether the file loads as a demo and holds every key of `require` besides the core."""
    try:
        demo = load_demo(path)
    except DemoError:
        return False
    return all(key in demo for key in require)
