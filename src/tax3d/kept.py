"""Kept JSON: the small file a command writes beside its output for a result page to read, such as OUT/summary.json.

Its values sit beside `kind` (what wrote it) and `version` (of that kind's fields, raised when they change), so that a
reader refuses a file of another kind, or of a version it does not read, in one line.
"""

from __future__ import annotations


def stamp(kind: str, version: int, values: dict) -> dict:
    """`values` as a kept file of `kind` at `version`."""
    return {"kind": kind, "version": version, **values}
