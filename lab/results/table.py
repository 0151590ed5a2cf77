"""The paper's table of a task beside ours, row by row, from the rows that `tax3d table --keep` writes.

Rows are kept as docs/results/table/TASK/DEMOS/VARIANT.json (kind "table-row"), every scoring of their test
episodes in docs/results/table/ledger.jsonl (tax3d.eval.ledger). The line above each table states its protocol from the
rows' own fields (the preset, plan, weights and test episodes most of them share, how often the ledger says they were
scored, the data draw the table names), and a row that departs from it says how in its last column: another preset
or plan, last weights, another draw or no digests recorded, scored more than once (with each earlier score). Every
row of the paper's table is listed at every training-set size; a row we have not run there yet says so. Below it,
each conclusion the paper draws from the table (its `claims` in paper.toml) is tested on our rows: a success rate is lower only when the two 95% intervals part ("holds"); when they overlap
the difference is "within noise".
"""

from __future__ import annotations

from collections import Counter
from pathlib import Path

from tax3d.eval import ledger as ledger_lines
from tax3d.errors import UsageError
from tax3d.metrics import rate, split_rate, success_interval
from tax3d.variants import FIXED_GOALS, ROWS, paper_key, row_name
from lab.results import kept
from lab.results.commands import shown

ORDER = tuple(paper_key(row) for row in ROWS)
FIXED = tuple(FIXED_GOALS)  # no paper row: the policy with the mean goal of train, and with each demo's own goal
PAPER_METRICS = {"rmse": "rmse", "coverage_rmse": "coverage", "precision_rmse": "precision"}  # ours: the paper's
SPLITS = ("train", "unseen", "ood")  # the columns of the paper's rows
DRAW_FOLDERS = ("train", "val", "unseen", "ood")


def load_rows(folder: Path) -> dict[int, dict[str, dict]]:
    """{training demos: {paper key: row}} of a task's kept rows; a file of another kind or version is an error."""
    rows: dict[int, dict[str, dict]] = {}
    for path in sorted(folder.glob("*/*.json")) if folder.is_dir() else []:
        row = kept.read(path, ("table-row",))
        rows.setdefault(int(path.parent.name), {})[paper_key(row["variant"])] = row
    return rows


def cell(value, fmt: str) -> str:
    return "-" if value is None else format(value, fmt)


def _success(row: dict | None, split: str) -> str:
    if row is None:
        return "not run yet"
    s = row["splits"][split]
    low, high = s["success_ci95"]
    return f"**{split_rate(s)}** ({low:.2f}-{high:.2f})"


def _rmse(row: dict | None, split: str) -> str:
    value = None if row is None else row["splits"][split].get("rmse")
    return "-" if value is None else f"{value:.3f}"


def _most(values, tie=None) -> object:
    """The value most rows share (on a tie the least by `tie`, else the first in the table's order); None where
    there is none."""
    counts = Counter(v for v in values if v is not None)
    order = list(counts)
    return min(counts, key=lambda v: (-counts[v], tie(v) if tie else order.index(v))) if counts else None


def _trained(row: dict) -> bool:
    return row.get("weights_sha256") is not None


def _test(row: dict) -> tuple:
    t = row["test"]
    return t["episodes"], t["first_index"], t["samples"]


def times(n: int) -> str:
    return "once" if n == 1 else "in no line of the ledger" if n == 0 else f"{n} times"


def _digest(value: str | None) -> str:
    return "none" if value is None else f"`{value[:8]}`"


def _earlier(line: dict) -> str:
    """An earlier scoring of a row, as the ledger holds it."""
    won, episodes = line.get("successes"), line.get("episodes") or {}
    result = ("no result kept" if won is None
              else " / ".join(rate(won[k], episodes[k]) for k in ("unseen", "ood") if k in won))
    weights = f", weights `{line['weights_sha256'][:8]}`" if line.get("weights_sha256") else ""
    source = f", {line['source']}" if line.get("source") else ""
    return f"{line.get('date') or 'undated'}: {result}{weights}{source}"


class Protocol:
    """What most rows of one table share, and how each row departs from it."""

    def __init__(self, task: str, demos: int, kept: dict[str, dict], lines: list[dict], draw: dict | None):
        trained = [r for r in kept.values() if _trained(r)]
        self.task, self.demos, self.lines, self.draw = task, demos, lines, draw
        self.preset = _most(r.get("preset") for r in trained)
        self.minutes = _most(r["minutes"] for r in trained)
        self.weights = _most(r["weights_chosen_on"] for r in trained)
        self.test = _most(_test(r) for r in kept.values())
        self.scored = _most((len(self.scorings(r)) for r in kept.values()), tie=lambda n: n)

    def scorings(self, row: dict) -> list[dict]:
        return ledger_lines.of_row(self.lines, self.task, self.demos, row["variant"])

    def line(self, like: str) -> str:
        episodes, first, samples = self.test
        weights = "weights chosen on `val`" if self.weights == "val" else f"weights: {self.weights}"
        draw = ("the table names no draw of its demonstrations" if self.draw is None else
                "on the draw " + ", ".join(f"{k} {_digest(self.draw[k])}" for k in DRAW_FOLDERS))
        return (f"**{self.demos} training demonstrations** ({like}); the protocol its rows share: `--preset "
                f"{self.preset}`, {self.minutes:g}-minute plans, {weights}; {episodes} test episodes a split "
                f"(demo_{first} on), {samples} goal samples an episode, scored {times(self.scored)} (the ledger's count); "
                f"{draw}. A row that departs from it says how in its last column. Success with its 95% Wilson "
                "interval:")

    def departures(self, row: dict) -> str:
        """How the row departs from the table's protocol, from its own fields and its lines in the ledger."""
        out = []
        if _trained(row):
            if row.get("preset") != self.preset:
                out.append(f"`--preset {row.get('preset')}`")
            if row["minutes"] != self.minutes:
                out.append(f"{row['minutes']:g}-minute plan")
            if row["weights_chosen_on"] != self.weights:
                out.append("last weights" if row["weights_chosen_on"] == "last step"
                           else f"weights: {row['weights_chosen_on']}")
        if _test(row) != self.test:
            episodes, first, samples = _test(row)
            out.append(f"{episodes} episodes from demo_{first}, {samples} samples")
        digests = row.get("data_sha256")
        if not digests:
            out.append("no data digests recorded")
        elif self.draw is not None and any(digests.get(k) != self.draw[k] for k in DRAW_FOLDERS):
            out.append("another draw: " + ", ".join(f"{k} {_digest(digests.get(k))}" for k in DRAW_FOLDERS
                                                    if digests.get(k) != self.draw[k]))
        scorings = self.scorings(row)
        if len(scorings) != self.scored:
            earlier = [_earlier(x) for x in scorings if not ledger_lines.is_kept_row(x, row)]
            out.append(f"scored {times(len(scorings))}" + (f"; earlier: {'; '.join(earlier)}" if earlier else ""))
        if scorings and not ledger_lines.is_kept_row(scorings[-1], row):
            out.append("its last scoring in the ledger is not the kept row")
        if row.get("trainings", 1) > 1:
            out.append(f"trained {row['trainings']} times")
        return "; ".join(out)


def check_draw(where: str, demos: int, draw: dict, kept: dict[str, dict]) -> dict:
    """A table's draw as its page names it: the four folders' digests, each one that a row of the table records."""
    if sorted(draw) != sorted(("demos", *DRAW_FOLDERS)):
        raise UsageError(f"{where}: draw of {demos} demos names {', '.join(sorted(draw))}; expected demos and the "
                         f"digests of {', '.join(DRAW_FOLDERS)}")
    for folder in DRAW_FOLDERS:
        if not any((r.get("data_sha256") or {}).get(folder) == draw[folder] for r in kept.values()):
            raise UsageError(f"{where}: draw of {demos} demos: {folder} {str(draw[folder])[:12]} is recorded by no row "
                             f"of the table; expected the digests a kept row records")
    return {k: draw[k] for k in DRAW_FOLDERS}


def markdown(task: str, paper: dict, rows: dict[int, dict[str, dict]], lines: list[dict] = (),
             draws: dict[int, dict] | None = None) -> list[str]:
    """One table per training-set size: each of the paper's rows, its success and RMSE beside ours (a row not kept
    at that size: "not run yet"), and how it departs from the protocol of the table; `lines` the ledger, `draws` the
    draw each table names (lab.results.table.check_draw)."""
    paper_rows = paper.get("rows", {})
    keys = [k for k in ORDER if k in paper_rows or k in FIXED]
    out = []
    paper_demos = paper.get("demos", [None])[0]
    for demos in sorted(rows):
        kept = rows[demos]
        protocol = Protocol(task, demos, kept, list(lines), (draws or {}).get(demos))
        like = "the paper's count" if demos == paper_demos else f"the paper trains on {paper_demos}"
        out += [protocol.line(like), "",
                "| row | success unseen | paper | success ood | paper | RMSE unseen | paper | RMSE ood | paper | "
                "departs from the protocol |",
                "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |"]
        for key in keys:
            row, theirs = kept.get(key), paper_rows.get(key, {})
            rmse = theirs.get("rmse", (None, None, None))
            success = theirs.get("success", (None, None, None))
            out.append(f"| {row_name(key)} | {_success(row, 'unseen')} | {cell(success[1], '.2f')} | "
                       f"{_success(row, 'ood')} | {cell(success[2], '.2f')} | {_rmse(row, 'unseen')} | "
                       f"{cell(rmse[1], '.3f')} | {_rmse(row, 'ood')} | {cell(rmse[2], '.3f')} | "
                       f"{'' if row is None else protocol.departures(row)} |")
        out.append("")
        out += _goal_table(keys, kept, paper_rows)
    out += conclusions(paper, rows)
    return out


def _goal_table(keys: list[str], kept: dict[str, dict], paper_rows: dict) -> list[str]:
    """Where the paper gives coverage and precision RMSE (two demonstrated goals a cloth), ours beside them."""
    if not any("coverage" in paper_rows.get(k, {}) for k in keys):
        return []
    lines = ["Coverage RMSE (for each demonstrated goal, the nearest of the goal samples) and precision RMSE (for each "
             "sample, the nearest demonstrated goal), beside the paper's:", "",
             "| row | coverage unseen | paper | precision unseen | paper | coverage ood | paper | precision ood | paper |",
             "| --- | --- | --- | --- | --- | --- | --- | --- | --- |"]
    for key in keys:
        row, theirs = kept.get(key), paper_rows.get(key, {})
        cells = []
        for split, column in (("unseen", 1), ("ood", 2)):
            for metric in ("coverage_rmse", "precision_rmse"):
                ours = None if row is None else row["splits"][split].get(metric)
                paper = theirs.get(PAPER_METRICS[metric], (None, None, None))[column]
                cells += [cell(ours, ".3f") if row is not None else "not run yet", cell(paper, ".3f")]
        lines.append(f"| {row_name(key)} | " + " | ".join(cells) + " |")
    return lines + [""]


HOLDS, FAILS, NOISE, MISSING = "holds", "does not hold", "within noise", "not run yet"


def _paper_success(paper_rows: dict, key: str, split: str) -> float:
    return paper_rows[key]["success"][SPLITS.index(split)]


def _value(row: dict, split: str, metric: str):
    s = row["splits"][split]
    return s["success_rate"] if metric == "success" else s.get(metric)


def _check(kept: dict, paper_rows: dict, claim: dict, worse: str, than: str | None) -> tuple[str, str]:
    """(verdict, the numbers behind it) of one comparison of a claim."""
    metric = claim.get("metric", "success")
    key, split = worse.split(":")
    row = kept.get(key)
    if row is None or (than is not None and kept.get(than.split(":")[0]) is None):
        return MISSING, f"{row_name(key)} {split}: {MISSING}"
    if than is None and metric != "success":  # `reaches` an error: ours at or below the paper's
        ours = row["splits"][split].get(metric)
        theirs = paper_rows[key][PAPER_METRICS[metric]][SPLITS.index(split)]
        verdict = HOLDS if ours is not None and ours <= theirs + claim.get("margin", 0.0) + 1e-9 else FAILS
        return verdict, f"{row_name(key)} {split} {cell(ours, '.3f')} (paper {theirs:.3f})"
    if than is None:  # `reaches`: our success against the paper's
        ours, theirs = row["splits"][split], _paper_success(paper_rows, key, split)
        verdict = HOLDS if ours["success_rate"] >= theirs - claim.get("margin", 0.0) - 1e-9 else FAILS
        return verdict, f"{row_name(key)} {split} {split_rate(ours)} (paper {theirs:.2f})"
    other_key, other_split = than.split(":")
    other = kept[other_key]
    a, b = _value(row, split, metric), _value(other, other_split, metric)
    shown = ((split_rate(row["splits"][split]), split_rate(other["splits"][other_split])) if metric == "success"
             else (f"{a:.2f}", f"{b:.2f}"))
    text = f"{row_name(key)} {split} {shown[0]} vs {row_name(other_key)} {other_split} {shown[1]}"
    if metric != "success":  # an RMSE: worse when it is `factor` times the other's
        return (HOLDS if a > claim.get("factor", 1.0) * b else FAILS), text
    if a >= b:
        return FAILS, text
    high, low = row["splits"][split]["success_ci95"][1], other["splits"][other_split]["success_ci95"][0]
    return (HOLDS if high < low else NOISE), text


def paper_as_rows(paper: dict) -> dict[str, dict]:
    """The paper's own rows in the shape of ours, each success with the Wilson interval of its episode count
    (`demos`), so that each claim's test can be run on the numbers it was drawn from."""
    counts, rows = paper.get("demos", []), {}
    for key, theirs in paper.get("rows", {}).items():
        splits = {}
        for i, split in enumerate(SPLITS):
            s = {ours: theirs[name][i] for ours, name in PAPER_METRICS.items() if name in theirs}
            if "success" in theirs and i < len(counts):
                s["success_rate"] = theirs["success"][i]
                s["success_ci95"] = list(success_interval(round(theirs["success"][i] * counts[i]), counts[i]))
            splits[split] = s
        rows[key] = {"splits": splits}
    return rows


def _verdict(verdicts: list[str]) -> str:
    for v in (MISSING, FAILS, NOISE):
        if v in verdicts:
            return v
    return HOLDS


def conclusions(paper: dict, rows: dict[int, dict[str, dict]]) -> list[str]:
    """Each of the paper's claims about this table, tested on our rows of each training-set size that has the
    rows it needs (the largest size lists every claim, those waiting on a row as not run yet)."""
    claims, paper_rows = paper.get("claims", []), paper.get("rows", {})
    if not claims or not rows:
        return []
    lines = ["**Conclusions.** Each claim the paper draws from this table, tested on our rows: a success is lower when "
             "the two 95% intervals part; an RMSE claim needs the stated factor. The same test on the paper's own rows "
             "(its episode counts give the intervals) is beside it.", ""]
    theirs = paper_as_rows(paper)
    for demos in sorted(rows):
        table = []
        for claim in claims:
            pairs = ([(w, None) for w in claim["reaches"]] if "reaches" in claim
                     else list(zip(claim["worse"], claim["than"], strict=True)))
            checks = [_check(rows[demos], paper_rows, claim, w, t) for w, t in pairs]
            verdict = _verdict([v for v, _ in checks])
            if verdict == MISSING and demos != max(rows):
                continue
            metric = claim.get("metric", "success")
            test = (f"{metric.replace('_', ' ')} at or below the paper's" if "reaches" in claim and metric != "success"
                    else "at or above the paper's minus %.2f" % claim.get("margin", 0.0) if "reaches" in claim
                    else "lower success" if metric == "success"
                    else f"{metric.replace('_', ' ')} over {claim.get('factor', 1.0):g}x")
            numbers = "; ".join(text for v, text in checks if v != MISSING) or "-"
            on_paper = "-" if "reaches" in claim else _verdict([_check(theirs, paper_rows, claim, w, t)[0]
                                                                for w, t in pairs])
            table.append(f"| {claim['claim']} ({claim['where']}) | {test} | {numbers} | **{verdict}** | {on_paper} |")
        if table:
            lines += [f"{demos} training demonstrations:", "",
                      "| the paper's claim | test | ours | verdict | on the paper's rows |",
                      "| --- | --- | --- | --- | --- |", *table, ""]
    return lines


def _gap(value: float) -> str:
    """A difference of two rates, to the places it needs (the paper's have two, ours up to three)."""
    return f"{value:.2f}" if abs(round(value, 2) - round(value, 3)) < 1e-9 else f"{value:.3f}"


def verdict(paper: dict, rows: dict[int, dict[str, dict]]) -> str:
    """One sentence: at each training-set size, whether TAX3D reaches the paper's success on the test splits."""
    claim = next((c for c in paper.get("claims", []) if "reaches" in c and c.get("metric", "success") == "success"),
                 None)
    if claim is None or not rows:
        return ""
    margin, parts = claim.get("margin", 0.0), []
    for demos in sorted(rows):
        refs = [ref.split(":") for ref in claim["reaches"]]
        gaps = [_paper_success(paper["rows"], key, split) - rows[demos][key]["splits"][split]["success_rate"]
                for key, split in refs if key in rows[demos]]
        if not gaps:
            continue
        short = [g for g in gaps if g > margin + 1e-9]
        parts.append(f"with {demos} training demonstrations " + (
            f"TAX3D's {len(gaps)} success rates reach the paper's (within {margin:.2f})" if not short else
            f"{len(short)} of TAX3D's {len(gaps)} success rates fall short of the paper's by "
            + (_gap(min(short)) if len(short) == 1 else f"{_gap(min(short))}-{_gap(max(short))}")))
    return ("Under one protocol, " + "; ".join(parts) + " (TAX3D-CD and TAX3D-CP on unseen and ood).") if parts else ""


def commands(rows: dict[int, dict[str, dict]], ledger: list[dict] = ()) -> list[str]:
    """Each kept row's command, machine, date, weights and how often the ledger says its test episodes were
    scored."""
    lines = []
    for demos in sorted(rows):
        for key in ORDER:
            row = rows[demos].get(key)
            if row is None:
                continue
            best = min(row["validations"], key=lambda v: v["val_rmse"]) if row["validations"] else None
            chosen = (f"best val RMSE {best['val_rmse']:.3f} at step {best['step']:,} of "
                      f"{row['validations'][-1]['step']:,}" if best else row["weights_chosen_on"])
            weights = (f"weights `{row['weights']}` ({chosen}), sha256 `{row['weights_sha256'][:12]}`"
                       if row["weights_sha256"] else "no weights (a fixed goal)")
            digests = row.get("data_sha256")  # rows kept before the digests were recorded have none
            episodes = ("" if digests is None else
                        f" (unseen `{digests['unseen'][:12]}`, ood `{digests['ood'][:12]}`)")
            scored = len(ledger_lines.of_row(list(ledger), row["task"], demos, row["variant"]))
            lines.append(f"- {row_name(key)}, {demos} demos: {shown(row['command'])} on {row['machine']}, "
                         f"{row['date']}; {weights}; test episodes{episodes} scored {times(scored)} (the ledger)"
                         + (f"; trained {row['trainings']} times, the earlier weights set aside by "
                                      "`--retrain` after a fix" if row.get("trainings", 1) > 1 else ""))
    return lines
