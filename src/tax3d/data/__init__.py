"""Demonstration files: `write_demo` makes one from your own clouds, `load_demo` reads one (docs/own-data.md)."""

from tax3d.data.format import DemoError, load_demo, write_demo

__all__ = ["DemoError", "load_demo", "write_demo"]
