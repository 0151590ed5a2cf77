"""The renderers of `python -m lab.results`, one module per kind of page, over the kept JSON that lab.results.kept
loads; the command itself (lab.results.build) holds the registry of kinds."""
