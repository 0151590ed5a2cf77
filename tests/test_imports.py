"""The import graphs: no two modules of the package import each other, the package never imports the lab (which is
not installed with it), inference does not import the training data, and the lab's result-page machinery has no
cycle and imports tax3d and lab modules at module level only.

A graph holds every import of a module of its tree, at module level or inside a function (one there must not hide a
cycle)."""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SRC = ROOT / "src"
RESULTS_TOOLING = ROOT / "lab" / "results"


def module_name(path: Path, base: Path) -> str:
    parts = path.relative_to(base).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def imports(path: Path, base: Path, modules: set[str] | None = None) -> set[str]:
    """The modules that the module at `path` (named from `base`) imports, anywhere in it: those among `modules`, or
    every name imported where `modules` is None."""
    name = module_name(path, base)
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    found = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            module = node.module or ""
            if node.level:
                anchor = package.split(".")[: len(package.split(".")) - node.level + 1]
                module = ".".join(anchor + ([module] if module else []))
            # `from tax3d.model import tax3d` imports the submodule; `from tax3d.model.tax3d import Tax3D` the module
            found.update(f"{module}.{alias.name}" if modules and f"{module}.{alias.name}" in modules else module
                         for alias in node.names)
    return found if modules is None else {m for m in found if m in modules and m != name}


def graph(folder: Path, base: Path) -> dict[str, set[str]]:
    """{module: the modules of the tree it imports} for every module under `folder`, named from `base`."""
    paths = sorted(folder.rglob("*.py"))
    modules = {module_name(p, base) for p in paths}
    return {module_name(p, base): imports(p, base, modules) for p in paths}


def package_graph() -> dict[str, set[str]]:
    return graph(SRC / "tax3d", SRC)


def test_no_two_modules_import_each_other():
    g = package_graph()
    mutual = {frozenset({a, b}) for a, targets in g.items() for b in targets if a in g.get(b, ())}
    assert mutual == set()


def test_the_package_never_imports_the_lab():
    for path in sorted((SRC / "tax3d").rglob("*.py")):
        names = imports(path, SRC)
        assert not any(n == "lab" or n.startswith("lab.") for n in names), f"{path.relative_to(ROOT)} imports the lab"


def test_the_results_tooling_has_no_import_cycle():
    g = graph(RESULTS_TOOLING, ROOT)
    assert {"lab.results.build", "lab.results.kept", "lab.results.pages.task", "lab.results.pages.card"} <= set(g)
    done: set[str] = set()

    def visit(name: str, path: tuple[str, ...]) -> None:
        assert name not in path, " -> ".join((*path, name))
        if name not in done:
            for target in g.get(name, ()):
                visit(target, (*path, name))
            done.add(name)

    for name in g:
        visit(name, ())


def test_the_results_tooling_imports_tax3d_and_lab_modules_at_module_level_only():
    for path in sorted(RESULTS_TOOLING.rglob("*.py")):
        for function in ast.walk(ast.parse(path.read_text())):
            if isinstance(function, (ast.FunctionDef, ast.AsyncFunctionDef)):
                for node in ast.walk(function):
                    names = ([a.name for a in node.names] if isinstance(node, ast.Import) else
                             [node.module or ""] if isinstance(node, ast.ImportFrom) else [])
                    assert not any(n.startswith(("tax3d", "lab")) or (isinstance(node, ast.ImportFrom) and node.level)
                                   for n in names), f"{path.name}: {function.name} imports {names}"


def test_the_model_and_the_config_do_not_import_the_training_data():
    g = package_graph()
    assert "tax3d.model.tax3d" in g and "tax3d.config" in g
    for name, targets in g.items():
        if name == "tax3d.config" or name.startswith("tax3d.model"):
            assert "tax3d.data.dataset" not in targets, name


# The package's layers, bottom first: a module imports only from its own layer and those below it. The top-level
# modules (errors, options, config, variants, geometry, checkpoint, ...) are the bottom layer.
LAYERS = ("tax3d.data", "tax3d.model", "tax3d.baselines", "tax3d.sim", "tax3d.training", "tax3d.policies",
          "tax3d.eval", "tax3d.cli")


def layer(module: str) -> int:
    return next((i + 1 for i, prefix in enumerate(LAYERS) if module == prefix or module.startswith(prefix + ".")),
                0)


def test_no_module_imports_a_layer_above_its_own():
    g = package_graph()
    assert {"tax3d.training.loop", "tax3d.eval.runner", "tax3d.cli.train", "tax3d.policies.goal"} <= set(g)
    upward = [f"{a} -> {b}" for a, targets in sorted(g.items()) for b in sorted(targets)
              if a != "tax3d" and layer(b) > layer(a)]  # `tax3d` itself: the front door, `from tax3d import Tax3D`
    assert upward == []


def test_the_package_imports_its_own_modules_at_module_level():
    """A function-level import would hide a dependency from the reader (and from the layer test); only the front
    door's lazy `Tax3D` (torch loads on first use, so the command line starts quickly) is one."""
    found = []
    for path in sorted((SRC / "tax3d").rglob("*.py")):
        for function in ast.walk(ast.parse(path.read_text())):
            if isinstance(function, (ast.FunctionDef, ast.AsyncFunctionDef)):
                for node in ast.walk(function):
                    names = ([a.name for a in node.names] if isinstance(node, ast.Import) else
                             [node.module or ""] if isinstance(node, ast.ImportFrom) else [])
                    if any(n.startswith("tax3d") for n in names) or (isinstance(node, ast.ImportFrom) and node.level):
                        found.append(f"{path.relative_to(SRC)}: {function.name}")
    assert found == ["tax3d/__init__.py: __getattr__"]
