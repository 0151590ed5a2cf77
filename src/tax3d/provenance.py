"""What made a result, where and when: the command, the machine line and the date kept beside every figure.

`tax3d.cli` names the command it runs (`running`); a result made from Python instead names the function's module.
"""

from __future__ import annotations

import datetime
import os
import platform
import shlex
from pathlib import Path

_running: list[str] | None = None  # the `tax3d` command line being run: its name and options


def running(argv: list[str] | None) -> None:
    """Record the `tax3d` command line this process runs (None: none)."""
    global _running
    _running = None if argv is None else list(argv)


def command(module: str) -> str:
    """The `tax3d` command line being run, as typed; where none is, `module` (called from Python)."""
    return "tax3d " + shlex.join(_running) if _running else f"{module}, called from Python"


def made(module: str) -> dict:
    """{"command", "machine", "date"} of a result made now."""
    return {"command": command(module), "machine": machine(), "date": today()}


def processor(cpuinfo: str | None = None) -> str | None:
    """The CPU's model name from /proc/cpuinfo, with "AVX-512" when its flags list it (the vector width torch's CPU
    kernels can use), or None where there is no such file (not Linux)."""
    if cpuinfo is None:
        path = Path("/proc/cpuinfo")
        if not path.is_file():
            return None
        cpuinfo = path.read_text(errors="replace")
    fields = {}
    for line in cpuinfo.splitlines():
        key, sep, value = line.partition(":")
        if sep:
            fields.setdefault(key.strip(), value.strip())
    name = fields.get("model name")
    if not name:
        return None
    return f"{name} with AVX-512" if "avx512f" in fields.get("flags", "").split() else name


def machine(*extra: str) -> str:
    """"x86_64, AMD EPYC, 2 cores, Python 3.11.7" (the processor where it is known), then any extra parts
    (a torch version, a GPU's name)."""
    cpu = processor()
    return ", ".join([platform.machine(), *([cpu] if cpu else []), f"{os.cpu_count()} cores",
                      f"Python {platform.python_version()}", *extra])


def today() -> str:
    """The local date, ISO 8601."""
    return datetime.date.today().isoformat()
