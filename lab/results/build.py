"""`python -m lab.results`: build the result pages of docs/results/ from their declarations and the kept JSON, or
--check them.

Each page is a TOML declaration in docs/results/pages/ whose `kind` (task when left out) picks its renderer below;
the renderers live in lab.results.pages, one module per kind, and read kept JSON through lab.results.kept. The
README's results table is built from the task pages, between `<!-- results -->` and `<!-- /results -->`. --check
compares markdown byte for byte and a plot by the JSON it was drawn from (lab.results.pages.plots).
"""

from __future__ import annotations

import sys
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, Optional

import tyro

from tax3d.atomic import write_bytes
from tax3d.cli import run_command
from tax3d.errors import UsageError
from lab.results.pages import plots
from lab.results.pages.card import CardsPage
from lab.results.pages.official import OfficialPage
from lab.results.pages.page import Page
from lab.results.pages.paper_count import PaperCountPage
from lab.results.pages.sim import SimPage
from lab.results.pages.speed import SpeedPage
from lab.results.pages.study import StudyPage
from lab.results.pages.task import TaskPage, readme_table

ROOT = Path(__file__).resolve().parents[2]
RENDERERS: dict[str, type[Page]] = {"task": TaskPage, "sim": SimPage, "official": OfficialPage, "speed": SpeedPage,
                                    "training": StudyPage, "cards": CardsPage, "paper-count": PaperCountPage}
MARKERS = ("<!-- results -->", "<!-- /results -->")
PROG = "python -m lab.results"
DESCRIPTION = "build the result pages of docs/results/ from their declarations, or --check them"


@dataclass
class Args:
    """Build the result pages of docs/results/ (and the README's results table, the model cards, docs/training.md's
    table) from docs/results/pages/*.toml."""

    pages: Annotated[tuple[str, ...], tyro.conf.Positional, tyro.conf.arg(metavar="[PAGE ...]")] = ()
    """pages, by their names (e.g. hangbag); default: every page"""
    check: bool = False
    """build in memory and exit 1, naming each file that differs from the one on disk"""
    root: Optional[str] = None
    """the results folder (default: docs/results of this checkout)"""


def declaration(file: Path) -> dict:
    try:
        spec = tomllib.loads(file.read_text())
    except tomllib.TOMLDecodeError as err:
        raise UsageError(f"{file}: not valid TOML ({err})") from None
    kind = spec.get("kind", "task")
    if kind not in RENDERERS:
        raise UsageError(f"{file.name}: kind {kind!r}: expected {', '.join(RENDERERS)}")
    return spec


def with_table(readme: str, table: str) -> str:
    start, end = readme.index(MARKERS[0]) + len(MARKERS[0]), readme.index(MARKERS[1])
    return readme[:start] + "\n" + table + "\n" + readme[end:]


def build(root: Path, only: tuple[str, ...] = ()) -> dict[Path, bytes]:
    """Every file the pages of `root` make (markdown, plots, model cards and the README's table), by path; those of
    the pages named `only` where it names any."""
    paper = tomllib.loads((root / "paper.toml").read_text())
    files = sorted((root / "pages").glob("*.toml"))
    names = [f.stem for f in files]
    unknown = [name for name in only if name not in names]
    if unknown:
        raise UsageError(f"page {unknown[0]!r}: expected one of {', '.join(names)}")
    out, pages = {}, []
    for f in files:
        if not only or f.stem in only:
            spec = declaration(f)
            pages.append(RENDERERS[spec.get("kind", "task")](f, root, paper, spec))
            out.update(pages[-1].files())
    readme = root.parent.parent / "README.md"
    if not only and readme.is_file() and MARKERS[0] in readme.read_text():
        table = readme_table([p for p in pages if isinstance(p, TaskPage)])
        out[readme] = with_table(readme.read_text(), table).encode()
    return out


def same(path: Path, data: bytes) -> bool:
    """Whether the file on disk is what was built: a plot by what it was drawn from, any other file byte for byte."""
    if not path.is_file():
        return False
    if path.suffix == ".png":
        return plots.drawn_from(path.read_bytes()) == plots.drawn_from(data) is not None
    return path.read_bytes() == data


def run(args: Args) -> int:
    root = Path(args.root) if args.root else ROOT / "docs" / "results"
    if not (root / "paper.toml").is_file():
        raise UsageError(f"--root {root}: expected a results folder with paper.toml and pages/")
    files = build(root, args.pages)
    if args.check:
        stale = [p for p, data in files.items() if not same(p, data)]
        for p in stale:
            print(f"{PROG}: {p} differs from what `{PROG}` builds", file=sys.stderr)
        return 1 if stale else 0
    for path, data in files.items():
        write_bytes(path, data)
        print(path)
    return 0


def main(argv: list[str] | None = None) -> int:
    """`python -m lab.results [PAGE ...] [--check] [--root FOLDER]`: bad input ends in one line, exit code 2."""
    argv = list(sys.argv[1:] if argv is None else argv)
    return run_command(PROG, sys.modules[__name__], DESCRIPTION, argv)
