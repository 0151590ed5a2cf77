"""The paper's table of a task beside ours, row by row, from the rows that `tax3d benchmark --keep` writes.

Rows are kept as docs/results/table/TASK/DEMOS/VARIANT.json (kind "table-row"): one protocol for all of them
(weights chosen on `val`, scored once on the test episodes). Every row of the paper's table is listed; a row we
have not run yet says so. Below it, each conclusion the paper draws from the table (its `claims` in paper.toml)
is tested on our rows: a success rate is lower only when the two 95% intervals part ("holds"); when they overlap
the difference is "within noise".
"""

from __future__ import annotations

from pathlib import Path

from tax3d import kept

ROW_KIND, ROW_VERSION = "table-row", 1
PAPER_KEYS = {"cd": "CD", "cp": "CP", "cd_w": "CD-W", "cp_w": "CP-W", "cd_nac": "CD-NAC", "cp_nac": "CP-NAC",
              "sd": "SD", "sp": "SP", "rd": "RD", "rp": "RP", "dp3": "DP3", "floor": "floor", "ceiling": "ceiling"}
ORDER = ("CD", "CP", "CD-W", "CP-W", "CD-NAC", "CP-NAC", "SD", "SP", "RD", "RP", "DP3", "floor", "ceiling")
FIXED = ("floor", "ceiling")  # no paper row: the policy with the mean goal of train, and with each demo's own goal
PAPER_METRICS = {"rmse": "rmse", "coverage_rmse": "coverage", "precision_rmse": "precision"}  # ours: the paper's
SPLITS = ("train", "unseen", "ood")  # the columns of the paper's rows
NAMES = {"CD": "TAX3D-CD", "CP": "TAX3D-CP", "floor": "mean goal of train (the floor)",
         "ceiling": "each demo's own goal (the ceiling)"}


def load_rows(folder: Path) -> dict[int, dict[str, dict]]:
    """{training demos: {paper key: row}} of a task's kept rows; a file of another kind or version is an error."""
    rows: dict[int, dict[str, dict]] = {}
    for path in sorted(folder.glob("*/*.json")) if folder.is_dir() else []:
        row = kept.read(path, (ROW_KIND,))
        rows.setdefault(int(path.parent.name), {})[PAPER_KEYS[row["variant"]]] = row
    return rows


def cell(value, fmt: str) -> str:
    return "-" if value is None else format(value, fmt)


def _success(row: dict | None, split: str) -> str:
    if row is None:
        return "not run yet"
    s = row["splits"][split]
    low, high = s["success_ci95"]
    return f"**{s['success_rate']:.2f}** ({low:.2f}-{high:.2f})"


def _rmse(row: dict | None, split: str) -> str:
    value = None if row is None else row["splits"][split].get("rmse")
    return "-" if value is None else f"{value:.3f}"


def markdown(task: str, paper: dict, rows: dict[int, dict[str, dict]]) -> list[str]:
    """One table per training-set size: each of the paper's rows (at smaller sizes, those we ran), its success and
    RMSE beside ours."""
    paper_rows = paper.get("rows", {})
    keys = [k for k in ORDER if k in paper_rows or k in FIXED]
    lines = []
    paper_demos = paper.get("demos", [None])[0]
    for demos in sorted(rows):
        kept = rows[demos]
        first = next((r for r in kept.values() if r.get("preset")), next(iter(kept.values())))
        like = "the paper's count" if demos == paper_demos else f"the paper trains on {paper_demos}"
        lines += [f"**{demos} training demonstrations** ({like}); every row `--preset {first['preset']}`, "
                  f"{first['minutes']:g}-minute plans on one core, weights chosen on `val`, scored once on "
                  f"{first['test']['episodes']} test episodes a split (demo_{first['test']['first_index']} on), "
                  f"{first['test']['samples']} goal samples an episode; success with its 95% Wilson interval:", "",
                  "| row | success unseen | paper | success ood | paper | RMSE unseen | paper | RMSE ood | paper |",
                  "| --- | --- | --- | --- | --- | --- | --- | --- | --- |"]
        # below the largest size only the rows run there (TAX3D-CD and -CP at the paper's count) are listed
        listed = keys if demos == max(rows) else [k for k in keys if k in kept]
        for key in listed:
            row, theirs = kept.get(key), paper_rows.get(key, {})
            rmse = theirs.get("rmse", (None, None, None))
            success = theirs.get("success", (None, None, None))
            lines.append(f"| {NAMES.get(key, key)} | {_success(row, 'unseen')} | {cell(success[1], '.2f')} | "
                         f"{_success(row, 'ood')} | {cell(success[2], '.2f')} | {_rmse(row, 'unseen')} | "
                         f"{cell(rmse[1], '.3f')} | {_rmse(row, 'ood')} | {cell(rmse[2], '.3f')} |")
        lines.append("")
        lines += _goal_table(listed, kept, paper_rows)
    lines += conclusions(paper, rows)
    return lines


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
        lines.append(f"| {NAMES.get(key, key)} | " + " | ".join(cells) + " |")
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
        return MISSING, f"{NAMES.get(key, key)} {split}: {MISSING}"
    if than is None and metric != "success":  # `reaches` an error: ours at or below the paper's
        ours = row["splits"][split].get(metric)
        theirs = paper_rows[key][PAPER_METRICS[metric]][SPLITS.index(split)]
        verdict = HOLDS if ours is not None and ours <= theirs + claim.get("margin", 0.0) + 1e-9 else FAILS
        return verdict, f"{NAMES.get(key, key)} {split} {cell(ours, '.3f')} (paper {theirs:.3f})"
    if than is None:  # `reaches`: our success against the paper's
        ours, theirs = row["splits"][split], _paper_success(paper_rows, key, split)
        verdict = HOLDS if ours["success_rate"] >= theirs - claim.get("margin", 0.0) - 1e-9 else FAILS
        return verdict, f"{NAMES.get(key, key)} {split} {ours['success_rate']:.2f} (paper {theirs:.2f})"
    other_key, other_split = than.split(":")
    other = kept[other_key]
    a, b = _value(row, split, metric), _value(other, other_split, metric)
    text = f"{NAMES.get(key, key)} {split} {a:.2f} vs {NAMES.get(other_key, other_key)} {other_split} {b:.2f}"
    if metric != "success":  # an RMSE: worse when it is `factor` times the other's
        return (HOLDS if a > claim.get("factor", 1.0) * b else FAILS), text
    if a >= b:
        return FAILS, text
    high, low = row["splits"][split]["success_ci95"][1], other["splits"][other_split]["success_ci95"][0]
    return (HOLDS if high < low else NOISE), text


def paper_as_rows(paper: dict) -> dict[str, dict]:
    """The paper's own rows in the shape of ours, each success with the Wilson interval of its episode count
    (`demos`), so that each claim's test can be run on the numbers it was drawn from."""
    from tax3d.metrics import success_interval

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
            + (f"{min(short):.2f}" if len(short) == 1 else f"{min(short):.2f}-{max(short):.2f}")))
    return ("Under one protocol, " + "; ".join(parts) + " (TAX3D-CD and TAX3D-CP on unseen and ood).") if parts else ""


def commands(rows: dict[int, dict[str, dict]]) -> list[str]:
    """Each kept row's command, machine, date, weights and how often its test episodes were scored."""
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
            lines.append(f"- {NAMES.get(key, key)}, {demos} demos: `{row['command']}` on {row['machine']}, "
                         f"{row['date']}; {weights}; test episodes{episodes} scored {row['test']['scorings']} "
                         "time(s)" + (f"; trained {row['trainings']} times, the earlier weights set aside by "
                                      "`--retrain` after a fix" if row.get("trainings", 1) > 1 else ""))
    return lines
