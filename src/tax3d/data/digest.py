"""sha256 digests of nested values (dicts, lists, arrays, plain values) and of demonstration files: equal digests,
equal contents, whatever the files' write times. The table's rows, the ledger, a run's OUT/demos.json and an
evaluation's kept episodes all digest this way."""

from __future__ import annotations

import hashlib
from pathlib import Path

import numpy as np

from tax3d.data.format import load_demo


def feed(h, value) -> None:
    """Feed `value` to the hash `h`: a dict by its sorted keys, a list or tuple item by item, an array by its dtype,
    shape and bytes, an object by its attributes, anything else by its repr."""
    if isinstance(value, dict):
        for key in sorted(value, key=str):
            h.update(str(key).encode())
            feed(h, value[key])
    elif isinstance(value, (list, tuple)):
        for item in value:
            feed(h, item)
    elif isinstance(value, np.ndarray):
        h.update(f"{value.dtype}{value.shape}".encode())
        h.update(np.ascontiguousarray(value).tobytes())
    elif hasattr(value, "__dict__"):  # such as the mean-goal baseline of an evaluation job
        feed(h, vars(value))
    else:
        h.update(repr(value).encode())


def demos_digest(files) -> str:
    """sha256 of the demos' names and the arrays they hold."""
    h = hashlib.sha256()
    for path in files:
        h.update(Path(path).name.encode())
        feed(h, load_demo(path))
    return h.hexdigest()
