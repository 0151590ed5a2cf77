"""The machine line and date kept beside every figure."""

import datetime
import os
import platform
import re

from tax3d import provenance


def test_machine_line_names_the_architecture_cores_and_python_then_the_extras():
    line = provenance.machine()
    parts = line.split(", ")
    assert parts[0] == platform.machine() and parts[0]
    assert re.fullmatch(r"\d+ cores", parts[1]) and int(parts[1].split()[0]) == os.cpu_count()
    assert re.fullmatch(r"Python 3\.\d+\.\d+", parts[2]) and len(parts) == 3
    assert provenance.machine("torch 2.0", "a GPU").split(", ") == parts + ["torch 2.0", "a GPU"]


def test_today_is_iso():
    assert re.fullmatch(r"\d{4}-\d{2}-\d{2}", provenance.today())
    assert datetime.date.fromisoformat(provenance.today()) == datetime.date.today()
