"""The result pages of docs/results/, built from their declarations and the kept JSON: `python -m lab.results`
(lab.results.build)."""
