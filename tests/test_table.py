"""The paper's table beside the rows `tax3d benchmark --keep` writes."""

import json
import tomllib

import pytest

from tax3d import table
from tax3d.errors import UsageError
from tax3d.results import ROOT


def row(variant: str, success: float, episodes: int = 40) -> dict:
    wins = round(success * episodes)
    from tax3d.metrics import success_interval

    split = lambda: {"episodes": episodes, "success_rate": wins / episodes,  # noqa: E731
                     "success_ci95": list(success_interval(wins, episodes)), "rmse": 0.4}
    return {"kind": "table-row", "version": 1, "task": "hangproccloth-unimodal", "variant": variant,
            "preset": "cpu", "minutes": 60.0, "num_train": 64, "weights": "best", "weights_chosen_on": "val",
            "weights_sha256": "ab" * 32, "validations": [{"step": 10, "val_rmse": 0.5}, {"step": 20, "val_rmse": 0.4}],
            "test": {"first_index": 100, "episodes": episodes, "samples": 5, "scorings": 1},
            "splits": {"unseen": split(), "ood": split()}, "command": "tax3d benchmark ...", "machine": "m",
            "date": "2026-12-05"}


def test_rows_beside_the_papers_with_intervals_and_gaps(tmp_path):
    folder = tmp_path / "hangproccloth-unimodal" / "64"
    folder.mkdir(parents=True)
    (folder / "cd.json").write_text(json.dumps(row("cd", 0.875)))
    paper = tomllib.loads((ROOT / "docs" / "results" / "paper.toml").read_text())["hangproccloth-unimodal"]
    rows = table.load_rows(tmp_path / "hangproccloth-unimodal")
    text = "\n".join(table.markdown("hangproccloth-unimodal", paper, rows))
    assert "| TAX3D-CD | **0.88** (0.74-0.95) | 0.90 |" in text  # ours with its Wilson interval, then the paper's
    assert "| TAX3D-CP | not run yet |" in text and "| DP3 | not run yet |" in text
    assert "64 training demonstrations** (the paper's count)" in text
    (line,) = table.commands(rows)
    assert "best val RMSE 0.400 at step 20 of 20" in line and "scored 1 time(s)" in line


def test_a_file_of_another_kind_is_refused(tmp_path):
    folder = tmp_path / "t" / "64"
    folder.mkdir(parents=True)
    (folder / "cd.json").write_text(json.dumps({**row("cd", 1.0), "kind": "summary"}))
    with pytest.raises(UsageError, match="expected a 'table-row' of version 1"):
        table.load_rows(tmp_path / "t")
