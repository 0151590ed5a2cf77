"""How many of the repository's kept command lines use each option of each `tax3d` command.

    python -m lab.studies.option_use [--at-most 0]

Reads every `command` kept in docs/results (its JSON and its page declarations), finds each `tax3d NAME ...` in it
(as the pages do, lab.results.commands), and counts, per option of today's `Args` of NAME (nested sections as
`--train.lr`), the command lines that name it. Prints one JSON object: {command: {option: count}}, only the options
named by at most `--at-most` lines (default: every option). docs/layout.md says why the rarely used ones stay.
"""

from __future__ import annotations

import argparse
import dataclasses
import importlib
import json
import re
import sys
from pathlib import Path

from tax3d.cli import COMMANDS
from lab.results.commands import renamed, tax3d_commands

ROOT = Path(__file__).resolve().parents[2]
RESULTS = ROOT / "docs" / "results"


def kept_commands() -> list[str]:
    """Every kept command line: the `command` fields of docs/results/**/*.json and the `tax3d ...` spans of the page
    declarations."""
    found: list[str] = []

    def walk(value) -> None:
        if isinstance(value, dict):
            for key, item in value.items():
                if key == "command" and isinstance(item, str):
                    found.append(item)
                else:
                    walk(item)
        elif isinstance(value, list):
            for item in value:
                walk(item)

    for path in sorted(RESULTS.rglob("*.json")):
        walk(json.loads(path.read_text()))
    for path in sorted((RESULTS / "pages").glob("*.toml")):
        found += re.findall(r"tax3d [a-z][a-z0-9-]* [^`\n\"]*", path.read_text())
    return found


def options_of(cls, prefix: str = "--") -> list[str]:
    """The option names of a command's Args, nested dataclass sections as `--section.field`."""
    names = []
    for f in dataclasses.fields(cls):
        default = f.default_factory() if f.default_factory is not dataclasses.MISSING else f.default
        if dataclasses.is_dataclass(default):
            names += options_of(type(default), f"{prefix}{f.name.replace('_', '-')}.")
        else:
            names.append(prefix + f.name.replace("_", "-"))
    return names


def count(commands: list[str]) -> dict[str, dict[str, int]]:
    used: dict[str, dict[str, int]] = {}
    for name, (module, _) in COMMANDS.items():
        options = options_of(importlib.import_module(module).Args)
        tally = dict.fromkeys(options, 0)
        for line in commands:
            named = {word.split("=")[0].replace("_", "-") for sub, argv in tax3d_commands(renamed(line))
                     if sub == name for word in argv if word.startswith("--")}
            for option in options:
                section, _, field = option[2:].rpartition(".")
                negated = f"--{section}.no-{field}" if section else f"--no-{field}"
                tally[option] += option in named or negated in named
        used[name] = tally
    return used


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--at-most", type=int, default=None, help="only the options named by at most this many lines")
    args = parser.parse_args(argv)
    used = count(kept_commands())
    if args.at_most is not None:
        used = {name: {o: n for o, n in tally.items() if n <= args.at_most} for name, tally in used.items()}
    print(json.dumps(used, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
