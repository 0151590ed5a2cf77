"""The machine line and date kept beside every figure."""

import datetime
import os
import platform
import re

from tax3d import provenance


def test_machine_line_names_the_architecture_processor_cores_and_python_then_the_extras():
    parts = provenance.machine().split(", ")
    assert parts[0] == platform.machine() and parts[0]
    cpu = provenance.processor()
    if cpu:
        assert parts[1] == cpu
        parts = [parts[0], *parts[2:]]
    assert re.fullmatch(r"\d+ cores", parts[1]) and int(parts[1].split()[0]) == os.cpu_count()
    assert re.fullmatch(r"Python 3\.\d+\.\d+", parts[2]) and len(parts) == 3
    assert provenance.machine("torch 2.0", "a GPU").endswith(", torch 2.0, a GPU")


def test_processor_reads_the_model_name_and_avx512():
    first = "processor\t: 0\nmodel name\t: Some CPU 9000\nflags\t\t: fpu sse avx2 {}\n\n"
    second = "processor\t: 1\nmodel name\t: Some CPU 9000\nflags\t\t: fpu\n"
    assert provenance.processor(first.format("") + second) == "Some CPU 9000"
    assert provenance.processor(first.format("avx512f avx512_bf16") + second) == "Some CPU 9000 with AVX-512"
    assert provenance.processor("processor\t: 0\nflags\t: avx512f\n") is None


def test_today_is_iso():
    assert re.fullmatch(r"\d{4}-\d{2}-\d{2}", provenance.today())
    assert datetime.date.fromisoformat(provenance.today()) == datetime.date.today()


def test_the_command_is_the_one_being_run_and_no_other(tmp_path, capsys):
    """A result made under `tax3d CMD` records that command line as typed; one made from Python after it names the
    module it was made by, not the command that ran before."""
    from tax3d import provenance
    from tax3d.cli import main

    assert provenance.command("tax3d.predict") == "tax3d.predict, called from Python"
    assert main(["predict", "--checkpoint", str(tmp_path / "none"), "--demos", str(tmp_path)]) == 2  # a usage error
    made = provenance.made("tax3d.cli.eval")  # after it, from Python: not the command that ran before
    assert made["command"] == "tax3d.cli.eval, called from Python" and "cores" in made["machine"] and made["date"]
