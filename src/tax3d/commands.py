"""Whether a kept `tax3d` command line still parses with today's options (a result page marks one that does not)."""

from __future__ import annotations

import contextlib
import functools
import importlib
import io
import shlex

import tyro

from tax3d.cli import COMMANDS
from tax3d.errors import UsageError

EARLIER = "recorded with an earlier version"


SEPARATORS = ("&&", "||", ";", "|")


def tax3d_commands(command: str) -> list[tuple[str, list[str]]]:
    """(subcommand, its arguments) of each `tax3d NAME ...` or `python -m tax3d.cli NAME ...` in a command line
    (commands joined by && or ; each)."""
    try:
        words = shlex.split(command.split(" #")[0])
    except ValueError:
        return []
    found, part = [], []
    for word in [*words, ";"]:
        if word not in SEPARATORS:
            part.append(word)
            continue
        start = next((i for i, w in enumerate(part[:-1]) if w.endswith("tax3d") or w == "tax3d.cli"), None)
        if start is not None:
            found.append((part[start + 1], part[start + 2:]))
        elif any(w.endswith("benchmarks/time_to_quality.py") for w in part):
            found += studied_runs(part)
        part = []
    return found


def studied_runs(words: list[str]) -> list[tuple[str, list[str]]]:
    """The `tax3d train` options of each `--run NAME OPTIONS` of benchmarks/time_to_quality.py, on its preset."""
    preset = words[words.index("--preset") + 1] if "--preset" in words[:-1] else "cpu"
    return [("train", ["--preset", preset, *shlex.split(words[i + 2])])
            for i, w in enumerate(words[:-2]) if w == "--run"]


@functools.lru_cache(maxsize=None)
def parses(command: str) -> bool:
    """False where today's version rejects the options of a `tax3d` command in the line; True otherwise."""
    return all(_parses(name, argv) for name, argv in tax3d_commands(command) if name in COMMANDS)


def _parses(name: str, argv: list[str]) -> bool:
    module = importlib.import_module(COMMANDS[name][0])
    try:
        with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
            if name == "train":
                module.config_of_command(argv)
            else:
                tyro.cli(module.Args, args=argv, prog=f"tax3d {name}")
    except (SystemExit, UsageError):
        return False
    return True


def shown(command: str) -> str:
    """A kept command as a page shows it: in backticks, marked where today's version no longer parses it."""
    return f"`{command}`" + ("" if parses(command) else f" ({EARLIER})")
