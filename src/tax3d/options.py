"""Checks of option values by kind, declared once on the field: `steps: Annotated[int, Positive] = 10`.

`check(args)` walks a command's `Args` (and nested sections such as `train.lr`) and raises a `UsageError` naming
the first option whose value is of the wrong kind, before any work starts. Output paths are checked for being
writable the same way (`OutputFile`, `OutputFolder`), so a typo costs a second, not an hour of evaluation. A check
that involves several options is a method `conflicts(self)` of the dataclass, yielding (option, value, problem)
after its fields pass. The command line runs `check` on parsing, and so do the library functions that take `Args`.
"""

from __future__ import annotations

import ast
import dataclasses
import inspect
import math
import os
import textwrap
import typing
from pathlib import Path

from tax3d.errors import UsageError


class Check:
    """A test of one option's value and the words for what it expects."""

    def __init__(self, test, expected: str):
        self.test, self.expected = test, expected

    def problem(self, value) -> str | None:
        return None if self.test(value) else f"expected {self.expected}"


def _finite(value) -> bool:
    values = value if isinstance(value, (tuple, list)) else (value,)
    return all(isinstance(v, (int, float)) and math.isfinite(v) for v in values)


Positive = Check(lambda v: _finite(v) and v > 0, "a positive number")
NonNegative = Check(lambda v: _finite(v) and v >= 0, "zero or a positive number")
Finite = Check(_finite, "finite numbers")
Fraction = Check(lambda v: _finite(v) and 0 <= v < 1, "a number in [0, 1)")


class _Output(Check):
    def __init__(self, kind: str):
        self.kind = kind
        super().__init__(None, "")

    def problem(self, value) -> str | None:
        return output_problem(Path(value), self.kind)


def output_problem(path: Path, kind: str) -> str | None:
    """Why `path` cannot be written as a `kind` ("file" or "folder"), or None when it can."""
    if kind == "folder" and path.exists() and not path.is_dir():
        return "is a file; expected a folder (new or existing) to write into"
    if kind == "file" and path.is_dir():
        return "is a folder; expected a file path"
    parent = path if kind == "folder" else path.parent
    while not parent.exists():
        parent = parent.parent
    if not parent.is_dir():
        return f"{parent} is a file; expected folders on the path"
    if not os.access(parent, os.W_OK | os.X_OK) or (path.exists() and not os.access(path, os.W_OK)):
        return f"{path if path.exists() else parent} is not writable"
    return None


OutputFile = _Output("file")
OutputFolder = _Output("folder")


def option_name(name: str) -> str:
    return "--" + name.replace("_", "-")


def problems(obj, prefix: str = ""):
    """(option, value, problem) for every checked field of a dataclass instance and its nested sections, then for
    each of its `conflicts` (checks across fields, run once its own fields pass)."""
    hints = typing.get_type_hints(type(obj), include_extras=True)
    passed = True
    for f in dataclasses.fields(obj):
        value = getattr(obj, f.name)
        name = prefix + f.name
        if dataclasses.is_dataclass(value):
            for found in problems(value, name + "."):
                passed = False
                yield found
            continue
        if value is None:
            continue
        for marker in getattr(hints[f.name], "__metadata__", ()):
            if isinstance(marker, Check):
                problem = marker.problem(value)
                if problem:
                    passed = False
                    yield name, value, problem
    if passed and hasattr(obj, "conflicts"):
        for name, value, problem in obj.conflicts():
            yield prefix + name, value, problem


def show(value) -> str:
    return " ".join(map(str, value)) if isinstance(value, (tuple, list)) else str(value)


def check(obj, prefix: str = "") -> None:
    """Raise a UsageError naming the first option of obj whose value fails its checks."""
    for name, value, problem in problems(obj, prefix):
        shown = show(value)
        raise UsageError(f"{option_name(name)} {shown}: {problem}" if shown else f"{option_name(name)}: {problem}")


def described(cls: type) -> type:
    """cls for the command line: each field's docstring as its --help (tax3d.config.field_docs), and the default
    shown once, by the docstring where it says "default: ...", else by the parser. Nested sections keep their own."""
    import tyro

    hints = typing.get_type_hints(cls, include_extras=True)
    docs = field_docs(cls)
    fields = []
    for f in dataclasses.fields(cls):
        default = {"default": f.default} if f.default is not dataclasses.MISSING else (
            {"default_factory": f.default_factory} if f.default_factory is not dataclasses.MISSING else {})
        doc = docs.get(f.name, "")
        hint = hints[f.name]
        if doc:
            arg = tyro.conf.arg(help=doc, **({"help_behavior_hint": ""} if "default:" in doc else {}))
            hint = typing.Annotated[hint, arg]
        fields.append((f.name, hint, dataclasses.field(**default)))
    return dataclasses.make_dataclass(cls.__name__, fields)


def parsed_as(cls: type, parsed) -> object:
    """An instance of cls with the values of `parsed`, an instance of described(cls)."""
    return cls(**{f.name: getattr(parsed, f.name) for f in dataclasses.fields(cls)})


def field_docs(cls: type) -> dict[str, str]:
    """The docstring under each field of a dataclass (the string right after it), on one line; a field declared in
    a base dataclass has the base's."""
    docs = {}
    for klass in reversed([k for k in cls.__mro__ if dataclasses.is_dataclass(k)]):
        body = ast.parse(textwrap.dedent(inspect.getsource(klass))).body[0].body
        docs.update({node.target.id: " ".join(after.value.value.split()) for node, after in zip(body, body[1:])
                     if isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name)
                     and isinstance(after, ast.Expr) and isinstance(after.value, ast.Constant)
                     and isinstance(after.value.value, str)})
    return docs
