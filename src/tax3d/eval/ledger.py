"""The ledger of test scorings: one JSON line for every scoring of the table's test episodes, kept in the repository.

`tax3d table` appends a line before it writes a row, and `tax3d eval` one when it scores test episodes (`unseen`
or `ood` at the indices the table scores, tax3d.sim.tasks.TEST_FIRST_INDEX on): the date, task, training demos,
row, weights sha, data digests, episodes and successes of each split. Deleting, training again or scoring again a row
never removes a line, so the pages count a row's scorings and show its earlier scores from here.

The ledger only grows: each line records the sha256 of every byte before it (`before_sha256`), and every reader and
writer checks the whole chain, so an earlier line edited or removed stops them in one line. The file is
docs/results/table/ledger.jsonl of the repository holding this package, or $TAX3D_LEDGER where set (a test's own
file); installed elsewhere without it, nothing is recorded.
"""

from __future__ import annotations

import fcntl
import hashlib
import json
import os
from pathlib import Path

from tax3d.data.digest import demos_digest
from tax3d.errors import UsageError
from tax3d.sim.tasks import TEST_FIRST_INDEX, get_task

ENV = "TAX3D_LEDGER"
REPOSITORY_LEDGER = Path(__file__).resolve().parents[3] / "docs" / "results" / "table" / "ledger.jsonl"
SPLITS = ("unseen", "ood")


def default_path() -> Path | None:
    """$TAX3D_LEDGER, else the repository's ledger where this package runs from a checkout, else None."""
    if os.environ.get(ENV):
        return Path(os.environ[ENV])
    return REPOSITORY_LEDGER if REPOSITORY_LEDGER.parent.is_dir() else None


def _lines(path: Path, text: str) -> list[dict]:
    """The lines of `text`, after checking that each one's before_sha256 is the hash of the text before it."""
    lines = []
    h = hashlib.sha256()
    for number, raw in enumerate(text.splitlines(keepends=True), 1):
        try:
            line = json.loads(raw)
        except ValueError as err:
            raise UsageError(f"{path}: line {number} is not valid JSON ({err}); expected one JSON object a line, "
                             f"as `tax3d table` appends them") from None
        if not isinstance(line, dict) or line.get("before_sha256") != h.hexdigest():
            raise UsageError(f"{path}: line {number} does not follow the lines before it (its before_sha256 is "
                             f"not the sha256 of the ledger up to it); expected earlier lines unchanged: the ledger "
                             f"only grows")
        lines.append(line)
        h.update(raw.encode())
    if text and not text.endswith("\n"):
        raise UsageError(f"{path}: its last line ends without a newline; expected whole lines only")
    return lines


def read(path: Path | None) -> list[dict]:
    """Every line of the ledger at `path` (none where it does not exist), its chain checked."""
    if path is None or not path.is_file():
        return []
    return _lines(path, path.read_text())


def append(path: Path | None, line: dict) -> dict | None:
    """Append `line` to the ledger at `path` (created where missing) under a lock, after checking every line
    already there; returns the line as written (None where there is no ledger)."""
    if path is None:
        return None
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "a+", encoding="utf-8") as f:
        fcntl.flock(f, fcntl.LOCK_EX)  # two rows scored side by side append one after the other
        f.seek(0)
        text = f.read()
        _lines(path, text)
        written = {**line, "before_sha256": hashlib.sha256(text.encode()).hexdigest()}
        f.write(json.dumps(written, sort_keys=True) + "\n")
        f.flush()
        os.fsync(f.fileno())
    return written


def successes(splits: dict) -> dict:
    """{split: episodes won} of a summary's test splits."""
    return {k: round(s["success_rate"] * s["episodes"]) for k, s in splits.items() if k in SPLITS}


def episodes(splits: dict) -> dict:
    return {k: s["episodes"] for k, s in splits.items() if k in SPLITS}


def scoring(task: str, num_train: int | None, row: str | None, summary: dict, digests: dict | None,
            first_index: int, command: str) -> dict:
    """The line of one scoring, from the summary that `tax3d eval` makes of it."""
    return {"date": summary["date"], "task": task, "num_train": num_train, "row": row,
            "weights_sha256": summary["weights_sha256"], "data_sha256": digests, "first_index": first_index,
            "episodes": episodes(summary["splits"]), "successes": successes(summary["splits"]), "command": command}


def of_row(lines: list[dict], task: str, num_train: int, row: str) -> list[dict]:
    """The scorings of one row of a table, oldest first."""
    return [x for x in lines if (x.get("task"), x.get("num_train"), x.get("row")) == (task, num_train, row)]


def is_kept_row(line: dict, row: dict) -> bool:
    """Whether the line is the scoring whose results the kept row holds."""
    return (line.get("weights_sha256") == row.get("weights_sha256")
            and line.get("successes") == successes(row["splits"]))


def _tests(first: int, episodes: int, size: int) -> bool:
    """Whether episodes first .. first + episodes - 1 reach the table's test indices of a split of `size`."""
    return first < TEST_FIRST_INDEX + size and first + episodes > TEST_FIRST_INDEX


def record_eval(args, summary: dict, demos) -> dict | None:
    """`tax3d eval`: a line where it scored test episodes, with the digests of the demos it read (`demos(split)`, the
    files; none where it drew the episodes from their seeds)."""
    task = get_task(args.task)
    tested = {k: s for k, s in summary["splits"].items()
              if k in SPLITS and _tests(args.first_index, s["episodes"], task.sizes[k])}
    if not tested:
        return None
    digests = None
    if args.data is not None:
        digests = {k: demos_digest(demos(k)) for k in tested}
    line = {**scoring(args.task, None, None, {**summary, "splits": tested}, digests, args.first_index,
                      summary["command"]), "checkpoint": summary["checkpoint"], "goal": summary["goal"]}
    return append(default_path(), line)
