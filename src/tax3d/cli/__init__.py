"""One entry point: `tax3d <command> [options]`; each command is a module with `Args` and `run(args)`."""

from __future__ import annotations

import importlib
import os
import sys
import warnings

from tax3d import options, provenance
from tax3d.atomic import WriteError
from tax3d.errors import UsageError

COMMANDS = {
    "generate": ("tax3d.cli.generate", "generate demonstrations in the official file layout"),
    "train": ("tax3d.cli.train", "train a TAX3D variant on demonstration folders"),
    "train-dp3": ("tax3d.cli.train_dp3", "train the DP3 baseline on demonstrations with trajectories"),
    "predict": ("tax3d.cli.predict", "predict goal clouds for demonstration files with a checkpoint"),
    "cloud": ("tax3d.cli.cloud", "turn a depth image, its mask, intrinsics and camera pose into a world-frame cloud"),
    "eval": ("tax3d.cli.eval", "evaluate a checkpoint: goal RMSE and policy success per split, with a report"),
    "table": ("tax3d.cli.table", "the paper's table of a task: generate, train and score each row, resumable"),
    "demo": ("tax3d.cli.demo", "the main job on the embedded default"),
}
RENAMED = {"benchmark": "table"}  # an earlier name of a command: its name today


def _usage() -> str:
    lines = ["usage: tax3d <command> [options]", "", "commands:"]
    lines += [f"  {name:<10} {help_}" for name, (_, help_) in COMMANDS.items()]
    lines += ["", "Run `tax3d <command> --help` for the options of a command."]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    if not argv:
        print(_usage(), file=sys.stderr)
        return 2
    if argv[0] in ("-h", "--help"):
        print(_usage())
        return 0
    name, rest = argv[0], argv[1:]
    if name in RENAMED:
        print(f"tax3d: error: `tax3d {name}` is renamed; use `tax3d {RENAMED[name]}` with the same options",
              file=sys.stderr)
        return 2
    if name not in COMMANDS:
        print(f"tax3d: error: unknown command {name!r}; expected one of {', '.join(COMMANDS)}", file=sys.stderr)
        return 2
    module = importlib.import_module(COMMANDS[name][0])
    provenance.running(argv)
    try:
        return run_command(f"tax3d {name}", module, COMMANDS[name][1], rest)
    finally:
        provenance.running(None)


def run_command(prog: str, module, description: str, argv: list[str]) -> int:
    """Parse `argv` into the module's `Args` and run it: bad input ends in one line and exit code 2, a failure
    partway in one line and exit code 1."""
    import tyro

    warnings.formatwarning = lambda message, category, *_: f"{prog}: warning: {message}\n"
    try:
        parsed = tyro.cli(options.described(module.Args), args=argv, prog=prog, description=description)
        args = options.parsed_as(module.Args, parsed)
        options.check(args)
        return int(module.run(args) or 0)
    except UsageError as err:
        print(f"{prog}: error: {err}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"{prog}: interrupted", file=sys.stderr)
        return 130
    except OSError as err:  # a full disk, a folder deleted underneath: the sentence of tax3d.atomic.WriteError
        print(f"{prog}: error: {os_failure(err)}", file=sys.stderr)
        return 1
    except Exception as err:
        if os.environ.get(TRACEBACK):
            raise
        print(f"{prog}: failed: {failure(err)} ({TRACEBACK}=1 shows where)", file=sys.stderr)
        return 1


TRACEBACK = "TAX3D_TRACEBACK"
"""set (to anything) in the environment: an unexpected error ends with its traceback instead of one line"""


def os_failure(err: OSError) -> str:
    if isinstance(err, WriteError) or not err.strerror:
        return str(err) or failure(err)
    reason = err.strerror[:1].lower() + err.strerror[1:]
    return f"{reason}: {err.filename}" if err.filename else reason


def failure(err: BaseException) -> str:
    text = str(err).strip().splitlines()
    return f"{type(err).__name__}: {text[0]}" if text else type(err).__name__
