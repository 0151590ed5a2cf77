"""The ledger of test scorings: it only grows, and `tax3d eval` writes to it only at the table's test indices."""

import json
from pathlib import Path

import pytest

from tax3d.eval import ledger
from tax3d.errors import UsageError

ROOT = Path(__file__).resolve().parents[1]


def line(row: str, won: int) -> dict:
    summary = {"date": "2026-12-06", "weights_sha256": "ab" * 32,
               "splits": {"unseen": {"episodes": 40, "success_rate": won / 40}, "ood": {"episodes": 40,
                                                                                      "success_rate": 0.0}}}
    return ledger.scoring("hangproccloth-simple", 16, row, summary, None, 100, "tax3d table ...")


def test_lines_are_appended_with_the_hash_of_what_was_before(tmp_path):
    path = tmp_path / "ledger.jsonl"
    ledger.append(path, line("sd", 30))
    ledger.append(path, line("sd", 40))
    lines = ledger.read(path)
    assert [x["successes"]["unseen"] for x in lines] == [30, 40] and lines[0]["episodes"] == {"unseen": 40, "ood": 40}
    assert len(ledger.of_row(lines, "hangproccloth-simple", 16, "sd")) == 2


@pytest.mark.parametrize("change", ["edit", "remove"])
def test_the_ledger_refuses_a_rewrite_of_an_earlier_line(tmp_path, change):
    path = tmp_path / "ledger.jsonl"
    for won in (30, 40, 35):
        ledger.append(path, line("sd", won))
    first, *rest = path.read_text().splitlines(keepends=True)
    edited = json.dumps({**json.loads(first), "successes": {"unseen": 40, "ood": 0}}, sort_keys=True) + "\n"
    path.write_text((edited if change == "edit" else "") + "".join(rest))
    says = r"ledger.jsonl: line \d does not follow the lines before it .* expected earlier lines unchanged"
    with pytest.raises(UsageError, match=says) as err:
        ledger.append(path, line("sd", 10))
    assert len(str(err.value).splitlines()) == 1
    with pytest.raises(UsageError, match=says):
        ledger.read(path)


def test_eval_records_only_the_tables_test_indices(tmp_path, own_ledger):
    from tax3d.cli.eval import Args

    summary = {"date": "2026-12-06", "weights_sha256": None, "command": "tax3d eval ...", "checkpoint": None,
               "goal": "mean", "splits": {"train": {"episodes": 40, "success_rate": 0.5},
                                          "unseen": {"episodes": 40, "success_rate": 0.075}}}
    for first in (0, 1000):  # the earlier pages' demo_0-39, the demo's fresh poses
        assert ledger.record_eval(Args(task="hangproccloth-simple", first_index=first), summary, None) is None
    written = ledger.record_eval(Args(task="hangproccloth-simple", first_index=100), summary, None)
    assert ledger.read(own_ledger) == [written] and written["successes"] == {"unseen": 3}
    assert written["row"] is None and written["goal"] == "mean"


def test_the_repositorys_ledger_holds_every_kept_row_and_only_grew_from_commit_to_commit():
    import subprocess

    lines = ledger.read(ledger.REPOSITORY_LEDGER)
    for path in sorted((ROOT / "docs" / "results" / "table").glob("*/*/*.json")):
        row = json.loads(path.read_text())
        scorings = ledger.of_row(lines, row["task"], row["num_train"], row["variant"])
        assert scorings and ledger.is_kept_row(scorings[-1], row), path  # the row is its last scoring
    rel = ledger.REPOSITORY_LEDGER.relative_to(ROOT)
    shas = subprocess.run(["git", "log", "--reverse", "--format=%H", "--", str(rel)], cwd=ROOT, capture_output=True,
                          text=True).stdout.split()
    texts = [subprocess.run(["git", "show", f"{sha}:{rel}"], cwd=ROOT, capture_output=True, text=True).stdout
             for sha in shas]
    for before, after in zip(texts, [*texts[1:], ledger.REPOSITORY_LEDGER.read_text()]):
        assert after.startswith(before)  # each commit only appended
