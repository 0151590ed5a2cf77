"""One run, one folder: a lock on a run's --out, held while the run writes there.

    with hold(out, "--out"):
        ...

The lock is an advisory lock (flock) on OUT/.lock, a file that records the holder's process id and is removed when
the run ends. The kernel releases the lock when the process ends, however it ends, so a crash or `kill -9` leaves
a file but no lock: the next run takes the file over and says whose it was. A second process asking for a held
lock is refused in one line.
"""

from __future__ import annotations

import contextlib
import fcntl
import os
import sys
from pathlib import Path

from tax3d.atomic import writing
from tax3d.errors import UsageError

LOCK_NAME = ".lock"


def alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # another user's process
        return True
    return True


def recorded_pid(path: Path) -> int | None:
    try:
        text = path.read_text().strip()
    except OSError:
        return None
    return int(text) if text.isdigit() else None


def acquire(path: Path, option: str) -> int:
    """A descriptor of `path` holding its lock. The file a holder removes on release may be opened just before:
    a lock taken on a file no longer at `path` is dropped and taken again."""
    while True:
        with writing(path):
            descriptor = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
        try:
            fcntl.flock(descriptor, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            os.close(descriptor)
            holder = recorded_pid(path)
            raise UsageError(f"{option} {path.parent}: another run{f' (process {holder})' if holder else ''} is "
                             f"writing there; expected a folder of its own (wait for that run to end, or use "
                             f"another {option})") from None
        try:
            if os.stat(path).st_ino == os.fstat(descriptor).st_ino:
                return descriptor
        except FileNotFoundError:
            pass
        os.close(descriptor)


@contextlib.contextmanager
def hold(out: Path, option: str = "--out"):
    """Create OUT if needed and hold its lock for the block; a folder this made and left empty is removed after."""
    out = Path(out)
    made = not out.exists()
    path = out / LOCK_NAME
    with writing(path):
        out.mkdir(parents=True, exist_ok=True)
    descriptor = acquire(path, option)
    try:
        previous = recorded_pid(path)
        if previous is not None and previous != os.getpid() and not alive(previous):
            print(f"{option} {out}: taking over the lock left by process {previous}, which is no longer running",
                  file=sys.stderr)
        with writing(path):
            os.ftruncate(descriptor, 0)
            os.pwrite(descriptor, f"{os.getpid()}\n".encode(), 0)
        yield
    finally:
        release(path, made)
        os.close(descriptor)


def release(path: Path, made: bool) -> None:
    """Remove the lock file (still locked, so no other run takes it meanwhile), and a folder made for nothing."""
    try:
        path.unlink()
        if made and not any(path.parent.iterdir()):
            path.parent.rmdir()
    except OSError:  # the folder is gone or not writable: the error that ended the run says so
        pass
