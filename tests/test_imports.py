"""The package's import graph: no two modules import each other, and inference does not import the training data.

The graph holds every import of a tax3d module, at module level or inside a function (one there must not hide a
cycle)."""

from __future__ import annotations

import ast
from pathlib import Path

SRC = Path(__file__).resolve().parents[1] / "src"

# Known, and to be undone by the results tooling's own rework (issue 42, item 3): results.py and results_pages.py.
KNOWN_MUTUAL = {frozenset({"tax3d.results", "tax3d.results_pages"})}


def module_name(path: Path) -> str:
    parts = path.relative_to(SRC).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def imports(path: Path, modules: set[str]) -> set[str]:
    """The tax3d modules that the module at `path` imports, anywhere in it."""
    name = module_name(path)
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    found = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join(anchor + ([base] if base else []))
            # `from tax3d.model import tax3d` imports the submodule; `from tax3d.model.tax3d import Tax3D` the module
            found.update(f"{base}.{alias.name}" if f"{base}.{alias.name}" in modules else base for alias in node.names)
    return {m for m in found if m in modules and m != name}


def graph() -> dict[str, set[str]]:
    paths = sorted(SRC.joinpath("tax3d").rglob("*.py"))
    modules = {module_name(p) for p in paths}
    return {module_name(p): imports(p, modules) for p in paths}


def test_no_two_modules_import_each_other():
    g = graph()
    mutual = {frozenset({a, b}) for a, targets in g.items() for b in targets if a in g.get(b, ())}
    assert mutual - KNOWN_MUTUAL == set()
    assert KNOWN_MUTUAL <= mutual, "a known pair no longer imports each other: drop it from KNOWN_MUTUAL"


def test_the_model_and_the_config_do_not_import_the_training_data():
    g = graph()
    assert "tax3d.model.tax3d" in g and "tax3d.config" in g
    for name, targets in g.items():
        if name == "tax3d.config" or name.startswith("tax3d.model"):
            assert "tax3d.data.dataset" not in targets, name
