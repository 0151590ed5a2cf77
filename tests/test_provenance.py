"""The machine line and date kept beside every figure."""

import datetime
import os
import platform
import re

from tax3d import provenance


def test_machine_line_and_extras():
    line = provenance.machine()
    assert line == f"{platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}"
    assert provenance.machine("torch 2.0", "a GPU") == line + ", torch 2.0, a GPU"


def test_today_is_iso():
    assert re.fullmatch(r"\d{4}-\d{2}-\d{2}", provenance.today())
    assert datetime.date.fromisoformat(provenance.today()) == datetime.date.today()
