"""The repository's lab, beside the installed package (src/tax3d) and not installed with it: the machinery that
builds the result pages of docs/results/ from kept JSON (lab.results) and the one-off studies whose JSON they keep
(lab.studies). Its modules run from the repository's root, e.g. `python -m lab.results --check` or
`python -m lab.studies.fidelity`."""
