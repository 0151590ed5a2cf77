"""The renderers of `tax3d results`, one module per kind of page, over the kept JSON that tax3d.kept loads; the
command itself (tax3d.results) holds the registry of kinds."""
