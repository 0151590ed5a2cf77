"""Atomic file writes: a temporary file beside the target, renamed over it, so no reader sees half a file.

A write that fails (a full disk, a folder deleted underneath) raises `WriteError`, an OSError whose message is one
sentence naming the file it was writing: "no space left on device writing runs/cd/last/model.safetensors"."""

from __future__ import annotations

import contextlib
import json
import os
import tempfile
from pathlib import Path
from typing import Callable


class WriteError(OSError):
    """A file or folder that could not be written, in one sentence."""

    def __init__(self, err: OSError, path):
        reason = getattr(err, "reason", None) or (err.strerror or str(err) or type(err).__name__).rstrip(".")
        self.reason, self.path = reason[:1].lower() + reason[1:], Path(path)
        super().__init__(err.errno, f"{self.reason} writing {path}")

    def __str__(self) -> str:
        return self.strerror

    def __reduce__(self):  # from a worker process: rebuilt from its parts, not from OSError's (errno, strerror)
        return _rebuilt, (self.errno, self.reason, str(self.path))


def _rebuilt(errno: int | None, reason: str, path: str) -> WriteError:
    return WriteError(OSError(errno, reason), path)


@contextlib.contextmanager
def writing(path):
    """OSErrors inside the block become a WriteError naming `path` (one already named passes as it is)."""
    try:
        yield
    except WriteError:
        raise
    except OSError as err:
        raise WriteError(err, path) from None


def atomic_write(path: str | os.PathLike, write: Callable[[Path], None]) -> Path:
    """Call write(tmp) on a fresh temporary path in path's folder, then rename it to `path`.

    On any error (or interrupt) the temporary file is removed and `path` is left as it was; an OSError is raised
    as a WriteError naming `path`.
    """
    path = Path(path)
    with writing(path):
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
        os.close(fd)
        try:
            write(Path(tmp))
            os.chmod(tmp, 0o644)
            os.replace(tmp, path)
        except BaseException:
            if os.path.exists(tmp):
                os.unlink(tmp)
            raise
    return path


def write_text(path: str | os.PathLike, text: str) -> Path:
    return atomic_write(path, lambda tmp: tmp.write_text(text))


def write_json(path: str | os.PathLike | None, obj, indent: int = 2) -> str:
    """The JSON text of obj, also written to path (a trailing newline added) unless path is None."""
    text = json.dumps(obj, indent=indent)
    if path is not None:
        write_text(path, text + "\n")
    return text


def write_bytes(path: str | os.PathLike, data: bytes) -> Path:
    return atomic_write(path, lambda tmp: tmp.write_bytes(data))
