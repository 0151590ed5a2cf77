"""Whether a kept command line still runs as written today: its `tax3d` options parse and the commands and scripts it
names are still there under the same names (a result page marks one that does not, with what to run today where there
is something)."""

from __future__ import annotations

import contextlib
import functools
import importlib
import io
import re
import shlex

import tyro

from tax3d import cli
from tax3d.cli import COMMANDS
from tax3d.errors import UsageError

EARLIER = "recorded with an earlier version"


SEPARATORS = ("&&", "||", ";", "|")
# scripts that kept command lines name, since replaced or removed: what to run today (None: nothing)
MOVED = {
    "scripts/oracle_policy.py": "`tax3d eval --goal demo` or `--goal mean` with the same options",
    "scripts/sampler_check.py": "`python -m lab.studies.samplers`, one checkpoint at a time",
    "scripts/keep_summary.py": "`tax3d eval`, which writes OUT/summary.json",
    "scripts/keep_log.py": "`tax3d train`, which writes OUT/summary.json",
    "scripts/val_curve.py": "`tax3d train`, which writes OUT/summary.json",
    "scripts/model_card.py": "`python -m lab.results model-cards`, from docs/results/pages/model-cards.toml",
    "scripts/precision_parts.py": None,
    "scripts/paper_budget_run.py": "`python benchmarks/paper_budget_run.py`",
    **{f"scripts/{name}.py": f"`python -m lab.studies.{name}`" for name in (
        "expert_rates", "fidelity", "goal_spread", "mode_spread", "official_report", "success_by_rmse")},
}
# the studies that moved from benchmarks/ to lab/studies/
STUDIES = ("paper_count", "time_to_quality", "fidelity", "official_report", "success_by_rmse", "goal_spread",
           "mode_spread", "expert_rates", "val_points", "generate_determinism", "samplers")
# commands that kept command lines name, since renamed or moved: the command that runs them today, with the same options
RENAMED = {
    **{f"{prefix} {old}": f"{prefix} {new}" for old, new in cli.RENAMED.items() for prefix in ("tax3d", "tax3d.cli")},
    "tax3d results": "python -m lab.results",
    **{f"python benchmarks/{name}.py": f"python -m lab.studies.{name}" for name in STUDIES},
}


def tax3d_commands(command: str) -> list[tuple[str, list[str]]]:
    """(subcommand, its arguments) of each `tax3d NAME ...` or `python -m tax3d.cli NAME ...` in a command line
    (commands joined by && or ; each), and the `tax3d train` of each run of `python -m lab.studies.time_to_quality`."""
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
        elif "lab.studies.time_to_quality" in part:
            found += studied_runs(part)
        part = []
    return found


def studied_runs(words: list[str]) -> list[tuple[str, list[str]]]:
    """The `tax3d train` options of each `--run NAME OPTIONS` of lab.studies.time_to_quality, on its preset."""
    preset = words[words.index("--preset") + 1] if "--preset" in words[:-1] else "cpu"
    return [("train", ["--preset", preset, *shlex.split(words[i + 2])])
            for i, w in enumerate(words[:-2]) if w == "--run"]


@functools.lru_cache(maxsize=None)
def parses(command: str) -> bool:
    """False where today's version rejects the options of a `tax3d` command in the line (under its name today);
    True otherwise."""
    return all(_parses(name, argv) for name, argv in tax3d_commands(renamed(command)) if name in COMMANDS)


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


def moved(command: str) -> str | None:
    """The script a command line names that has since been replaced or removed, or None."""
    return next((script for script in MOVED if script in command), None)


def renamed(command: str) -> str:
    """The command line with each command it names that has since been renamed or moved under its name today."""
    for old, new in RENAMED.items():
        command = _whole(old).sub(new, command)
    return command


def _whole(name: str) -> re.Pattern:
    """A command's name as whole words of a command line."""
    return re.compile(rf"\b{re.escape(name)}\b")


def shown(command: str) -> str:
    """A kept command as a page shows it: in backticks, marked where today's version no longer runs it as written,
    with what to run today."""
    script = moved(command)
    if script is not None:
        today = MOVED[script]
        return f"`{command}` ({EARLIER}" + (f"; today: {today})" if today else "; the script has since been removed)")
    if renamed(command) == command:
        return f"`{command}`" + ("" if parses(command) else f" ({EARLIER})")
    names = " and ".join(f"`{new}`" for old, new in RENAMED.items() if _whole(old).search(command))
    return f"`{command}` ({EARLIER}; today: {names}" + (" with the same options)" if parses(command) else ")")
