"""The HangProcCloth and HangBag scenes in PyBullet."""

import ctypes
import os
import sys


def _import_pybullet_quietly() -> None:
    """Import pybullet with file descriptors 1 and 2 closed off: its C code prints its build time on import."""
    sys.stdout.flush()
    sys.stderr.flush()
    saved = {fd: os.dup(fd) for fd in (1, 2)}
    devnull = os.open(os.devnull, os.O_WRONLY)
    for fd in saved:
        os.dup2(devnull, fd)
    try:
        import pybullet  # noqa: F401
    finally:
        ctypes.CDLL(None).fflush(None)  # the C library's buffers hold the line until flushed
        for fd, copy in saved.items():
            os.dup2(copy, fd)
            os.close(copy)
        os.close(devnull)


_import_pybullet_quietly()
