"""The package's import graph: no two modules import each other, the results tooling has no cycle and imports
tax3d modules at module level only, and inference does not import the training data.

The graph holds every import of a tax3d module, at module level or inside a function (one there must not hide a
cycle)."""

from __future__ import annotations

import ast
from pathlib import Path

SRC = Path(__file__).resolve().parents[1] / "src"
RESULTS_TOOLING = ("tax3d.results", "tax3d.kept", "tax3d.pages")


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
    assert mutual == set()


def tooling(name: str) -> bool:
    return any(name == m or name.startswith(m + ".") for m in RESULTS_TOOLING)


def test_the_results_tooling_has_no_import_cycle():
    g = {name: {t for t in targets if tooling(t)} for name, targets in graph().items() if tooling(name)}
    assert {"tax3d.results", "tax3d.kept", "tax3d.pages.task", "tax3d.pages.card"} <= set(g)
    done: set[str] = set()

    def visit(name: str, path: tuple[str, ...]) -> None:
        assert name not in path, " -> ".join((*path, name))
        if name not in done:
            for target in g.get(name, ()):
                visit(target, (*path, name))
            done.add(name)

    for name in g:
        visit(name, ())


def test_the_results_tooling_imports_tax3d_modules_at_module_level_only():
    for path in sorted(SRC.joinpath("tax3d").rglob("*.py")):
        if not tooling(module_name(path)):
            continue
        for function in ast.walk(ast.parse(path.read_text())):
            if isinstance(function, (ast.FunctionDef, ast.AsyncFunctionDef)):
                for node in ast.walk(function):
                    names = ([a.name for a in node.names] if isinstance(node, ast.Import) else
                             [node.module or ""] if isinstance(node, ast.ImportFrom) else [])
                    assert not any(n.startswith("tax3d") or (isinstance(node, ast.ImportFrom) and node.level)
                                   for n in names), f"{path.name}: {function.name} imports {names}"


def test_the_model_and_the_config_do_not_import_the_training_data():
    g = graph()
    assert "tax3d.model.tax3d" in g and "tax3d.config" in g
    for name, targets in g.items():
        if name == "tax3d.config" or name.startswith("tax3d.model"):
            assert "tax3d.data.dataset" not in targets, name
