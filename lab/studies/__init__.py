"""The one-off studies whose kept JSON the result pages read: the scene's fidelity, the pseudo-expert's rates, goal and
mode spreads, samplers, training time to quality, the paper's demonstration count. Each runs from the repository's
root as `python -m lab.studies.NAME` and records that command line in what it keeps."""

from __future__ import annotations

import shlex


def command_line(module: str, argv: list[str]) -> str:
    """The command line a study records: `python -m MODULE ARGV`."""
    return shlex.join(["python", "-m", module, *argv])
