"""`tax3d results`: pages built from declarations and kept summaries, --check, bad input, the paper's data file."""

from __future__ import annotations

import json
import re
import shutil
import tomllib
from pathlib import Path

import pytest

from tax3d import results
from tax3d.cli import main

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "docs" / "results"

PAGE = '''
title = "Fixture task"
task = "hangproccloth-unimodal"
headline = ["cd", "paper:CD", "floor"]
readme = { task = "Fixture", row = "cd", paper = "CD", order = 1 }
verdict = "TAX3D-CD hangs {cd.unseen.success} of `unseen` cloths against the paper's {paper.CD.success.unseen}."
definitions = "RMSE and success as defined."

[[note]]
title = "Reading the table"
text = "The floor hangs {floor.ood.success} of `ood` cloths; TAX3D-CD's RMSE there is {cd.ood.rmse:.3f}."

[[row]]
id = "cd"
label = "TAX3D-CD, cpu preset, fixture"
summary = "evals/cd.json"
paper = "CD"
made = "tax3d train --preset cpu --out runs/cd"

[[row]]
id = "floor"
label = "mean goal of train (the floor)"
summary = "evals/floor.json"

[[curve]]
id = "cd-curve"
label = "TAX3D-CD"
summary = "evals/cd-curve.json"
'''


def eval_summary(success: float, rmse: float) -> dict:
    split = {"episodes": 20, "success_rate": success, "rmse": rmse, "coverage_rmse": rmse / 2,
             "precision_rmse": rmse, "predict_seconds": 0.5, "sim_seconds": 4.0, "failed_runs": 0}
    return {"summary": {"checkpoint": "runs/cd/best", "task": "hangproccloth-unimodal", "command": "tax3d eval ...",
                        "machine": "test machine", "date": "2026-01-01", "policy_offset": [0.0, 0.0, 0.0],
                        "splits": {k: dict(split) for k in results.SPLITS}}}


@pytest.fixture
def root(tmp_path: Path) -> Path:
    """A results folder: the paper's data file, one page declaration and its kept summaries."""
    (tmp_path / "pages").mkdir()
    (tmp_path / "evals").mkdir()
    shutil.copy(RESULTS / "paper.toml", tmp_path / "paper.toml")
    (tmp_path / "pages" / "fixture.toml").write_text(PAGE)
    (tmp_path / "evals" / "cd.json").write_text(json.dumps(eval_summary(0.75, 0.8125)))
    floor = {"command": "python scripts/oracle_policy.py --goal mean", "goal": "mean", "offset": [0.0, 0.0, 0.0],
             "machine": "test machine", "date": "2026-01-02",
             "splits": {k: {"episodes": 20, "success_rate": 0.25, "rmse": 1.5} for k in results.SPLITS}}
    (tmp_path / "evals" / "floor.json").write_text(json.dumps(floor))
    curve = {"run": "runs/cd", "val": ["data/u/unseen"], "val_demos": 10, "val_samples": 2, "steps": 2000,
             "points": [{"step": 1000, "val_rmse": 2.5}, {"step": 2000, "val_rmse": 1.25}]}
    (tmp_path / "evals" / "cd-curve.json").write_text(json.dumps(curve))
    return tmp_path


def test_page_from_fixture_summaries(root, capsys):
    assert main(["results", "--root", str(root)]) == 0
    text = (root / "fixture.md").read_text()
    assert text.startswith("# Fixture task\n\nTAX3D-CD hangs 0.75 of `unseen` cloths against the paper's 0.90.\n")
    assert "| TAX3D-CD, cpu preset, fixture | 0.75 | 0.75 | 0.75 | 0.812 | 0.812 | 0.812 | 20 / 20 / 20 |" in text
    assert "| TAX3D-CD, the paper | 0.94 | 0.90 | 0.85 | 0.052 | 0.405 | 0.395 | 64 / 40 / 40 |" in text
    assert "| mean goal of train (the floor) | 0.25 | 0.25 | 0.25 | 1.500 | 1.500 | 1.500 | 20 / 20 / 20 |" in text
    assert "The floor hangs 0.25 of `ood` cloths; TAX3D-CD's RMSE there is 0.812." in text
    assert "| 2,000 | 1.250 |" in text  # the validation curve
    assert "`tax3d train --preset cpu --out runs/cd`" in text and "test machine, 2026-01-01" in text
    assert (root / "fixture.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert main(["results", "--root", str(root), "--check"]) == 0


def test_plot_is_the_same_on_every_run(root):
    first = results.build(root)
    assert first == results.build(root)


def test_check_names_a_page_whose_summary_changed(root, capsys):
    assert main(["results", "--root", str(root)]) == 0
    (root / "evals" / "cd.json").write_text(json.dumps(eval_summary(0.5, 0.8125)))
    capsys.readouterr()
    assert main(["results", "--root", str(root), "--check"]) == 1
    err = capsys.readouterr().err
    assert "fixture.md differs" in err
    assert main(["results", "fixture", "--root", str(root), "--check"]) == 1


def test_missing_summary_names_the_row(root, capsys):
    (root / "evals" / "floor.json").unlink()
    assert main(["results", "--root", str(root)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "row 'floor'" in err and "evals/floor.json not found" in err
    assert not (root / "fixture.md").exists()


@pytest.mark.parametrize("argv, words", [(["nope"], "page 'nope': expected one of fixture"),
                                        (["--root", "/nonexistent"], "--root /nonexistent: expected a results folder")])
def test_bad_options_are_one_line_exit_2(root, capsys, argv, words):
    assert main(["results", *argv] + ([] if "--root" in argv else ["--root", str(root)])) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and words in err, err


def test_placeholder_without_a_value_is_an_error(root, capsys):
    page = root / "pages" / "fixture.toml"
    page.write_text(page.read_text().replace("{cd.ood.rmse:.3f}", "{cd.ood.nothing}"))
    assert main(["results", "--root", str(root)]) == 2
    assert "placeholder {cd.ood.nothing}" in capsys.readouterr().err


def test_paper_data_file_against_the_paper_text():
    # Typed from the tables of the paper's appendix D, independently of docs/results/paper.toml.
    paper = tomllib.loads((RESULTS / "paper.toml").read_text())
    assert paper["hangproccloth-unimodal"]["rows"]["CD"]["success"] == [0.94, 0.90, 0.85]
    assert paper["hangproccloth-unimodal"]["rows"]["CP-W"]["rmse"][2] == 19.923
    assert paper["hangproccloth-simple"]["rows"]["SP"]["success"] == [0.50, 0.58, 0.05]
    assert paper["hangproccloth-simple"]["rows"]["CD"]["rmse"] == [0.270, 0.255, 0.498]
    assert paper["hangproccloth-multimodal"]["rows"]["RP"]["coverage"] == [1.360, 1.417, 1.432]
    assert paper["hangproccloth-multimodal"]["rows"]["CP-W"]["precision"][2] == 47.372
    assert paper["hangproccloth-multimodal"]["rows"]["RD"]["success"] == [0.53, 0.60, 0.50]
    assert paper["hangbag"]["rows"]["CP-NAC"]["rmse"] == [1.485, 1.487, 1.486]
    assert paper["hangbag"]["rows"]["CP"]["success"] == [0.94, 0.93, 0.78]
    assert "rmse" not in paper["hangbag"]["rows"]["DP3"]
    assert paper["training"]["epochs"] == 20000


def _prose(text: str) -> list[str]:
    """The paragraphs outside <details>, tables, headings and images."""
    text = re.sub(r"<details>.*?</details>", "", text, flags=re.S)
    return [p for p in text.split("\n\n") if p.strip() and not p.lstrip().startswith(("|", "#", "!["))]


def test_no_paragraph_over_120_words_outside_details():
    for path, data in results.build(RESULTS).items():
        if path.suffix == ".md" and path.name != "README.md":
            for paragraph in _prose(data.decode()):
                assert len(paragraph.split()) <= 120, f"{path.name}: {paragraph[:80]}..."


def test_notes_have_no_hand_typed_numbers():
    """A number in a verdict or note comes from a kept summary through a placeholder."""
    for file in sorted((RESULTS / "pages").glob("*.toml")):
        spec = tomllib.loads(file.read_text())
        texts = [spec["verdict"], spec.get("sets_note", ""), spec.get("spread_note", "")]
        texts += [n["text"] for n in spec.get("note", []) + spec.get("ablation_note", [])]
        for text in texts:
            bare = re.sub(r"`[^`]*`|\]\([^)]*\)|\b(TAX3D|DP3)\b", "", results.PLACEHOLDER.sub("", text))
            assert not re.search(r"\d", bare), f"{file.name}: a hand-typed number in {bare[:200]!r}"


def test_committed_pages_are_what_tax3d_results_builds(capsys):
    assert main(["results", "--check"]) == 0, capsys.readouterr().err
