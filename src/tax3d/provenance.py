"""Where and when a result was made: the machine line and the date kept beside every figure."""

from __future__ import annotations

import datetime
import os
import platform


def machine(*extra: str) -> str:
    """"x86_64, 2 cores, Python 3.11.7", then any extra parts (a torch version, a GPU's name)."""
    return ", ".join([platform.machine(), f"{os.cpu_count()} cores", f"Python {platform.python_version()}", *extra])


def today() -> str:
    """The local date, ISO 8601."""
    return datetime.date.today().isoformat()
