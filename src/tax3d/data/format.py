"""The demonstration file: the official npz layout, validated, loaded safely, written atomically."""

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

ARRAY_KEYS = ("action_pc", "action_seg", "anchor_pc", "anchor_seg", "flow", "speed_factor", "rot", "trans")
OBJECT_KEYS = ("deform_params", "anchors")
REQUIRED_KEYS = ARRAY_KEYS + OBJECT_KEYS
# deform_params of a HangBag demo: the procedural bag's sizes (tax3d.sim.bag.BagParams).
BAG_KEYS = frozenset({"width", "depth", "height", "handle_gap", "handle_rise", "strap", "spacing", "handle_segments"})
# Coordinates of a scene are tens of units; values beyond this are a broken file, and would overflow in training.
MAX_COORDINATE = 1e6
# Optional per-step trajectory arrays written by `tax3d generate --trajectories` (for the DP3 baseline).
TRAJECTORY_PREFIX = "traj_"

_DEMO_NAME = re.compile(r"^demo_(\d+)\.npz$")


class DemoError(UsageError):
    """A demonstration file that is missing, unreadable or malformed."""


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
            missing = [k for k in REQUIRED_KEYS if k not in names]
            if missing:
                raise DemoError(f"{path}: missing keys {missing}; expected all of {list(REQUIRED_KEYS)}")
            demo = {}
            for key in sorted(names):
                if key in OBJECT_KEYS:
                    demo[key] = _to_plain(_read_object(zf, key))
                else:
                    demo[key] = _read_array(zf, key)
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
        if not isinstance(value, np.ndarray) or value.shape != shape:
            raise DemoError(f"{path}: {key} has shape {getattr(value, 'shape', None)}; expected {shape}")
    for key in ("action_pc", "anchor_pc", "flow", "rot", "trans"):
        if demo[key].dtype.kind not in "fiu":
            raise DemoError(f"{path}: {key} has dtype {demo[key].dtype}; expected real numbers")
        if not np.all(np.isfinite(demo[key])):
            raise DemoError(f"{path}: {key} contains NaN or infinite values")
        if np.abs(demo[key]).max(initial=0.0) > MAX_COORDINATE:
            raise DemoError(f"{path}: {key} has values beyond {MAX_COORDINATE:g}; expected scene coordinates")
    params = demo.get("deform_params")
    if not (isinstance(params, dict) and BAG_KEYS <= set(params)):  # a bag's sizes are checked when it is built
        _validate_cloth_dict(params, path)
    if not isinstance(demo.get("anchors"), dict):
        raise DemoError(f"{path}: anchors is not a dict of gripper id -> {{pos, vertices}}")


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
    missing = [k for k in REQUIRED_KEYS if k not in demo]
    if missing:
        raise ValueError(f"demo for {path} lacks keys {missing}")
    validate_demo(demo, path)
    arrays = {}
    for key, value in demo.items():
        if key in OBJECT_KEYS:
            holder = np.empty((), dtype=object)
            holder[()] = value
            arrays[key] = holder
        else:
            arrays[key] = np.asarray(value)
    def write(tmp: Path) -> None:
        with open(tmp, "wb") as f:  # a file object, so numpy does not append ".npz" to the temporary name
            np.savez(f, **arrays)

    atomic_write(path, write)


def grip_vertices(demo: dict) -> list[int]:
    """The action-cloud rows the demo's grippers hold: the vertices of its `anchors`."""
    return [int(v) for gripper in demo["anchors"].values() for v in gripper["vertices"]]


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


def is_valid_demo(path: str | os.PathLike) -> bool:
    try:
        load_demo(path)
        return True
    except DemoError:
        return False
