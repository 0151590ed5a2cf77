"""A task's page (docs/results/TASK.md): the verdict, the table of its headline rows beside the paper's, their plot,
then every row, the ablations, coverage and precision, validation curves, the notes and every command.

Beside what every declaration holds (lab.results.pages.page), a task page's holds `task` (its key in paper.toml),
`headline` (at most 8 row ids or `paper:ROW`), optional `grip` and `check` (the policy's targets and the success check
where they differ from shared.toml's), `definitions` (said after the shared ones), `readme`, `setup`, `sets`,
`sets_note` (after the shared definition of coverage and precision), `spread_note`, and arrays of tables `row` (id,
label: a fixed-goal row's defaults to shared.toml's, summary: a kept evaluation, optional paper, group = "ablation",
made, config, shipped), `curve` (id, label, summary: a kept validation curve or training log) and `draw`
(demos, and the digests of train, val, unseen and ood: the draw of the demonstrations that table of the protocol
names, lab.results.table.check_draw). Where `tax3d table --keep` has kept rows for the task
(docs/results/table/TASK/), the paper's table under that one protocol comes first, each row's scorings from the
ledger (docs/results/table/ledger.jsonl).
"""

from __future__ import annotations

from pathlib import Path

from tax3d.eval import ledger
from tax3d.errors import UsageError
from tax3d.metrics import split_rate
from tax3d.variants import paper_key, row_name
from lab.results import table
from lab.results.commands import EARLIER, shown
from lab.results.pages import plots
from lab.results.pages.card import shipped_rows
from lab.results.pages.page import SPLITS, Page, cell, fold, shared, slots



class TaskPage(Page):
    required = ("title", "task", "verdict", "headline")

    def __init__(self, *args):
        super().__init__(*args)
        if len(self.spec.get("headline", ())) > 8:
            raise UsageError(f"{self.file.name}: headline has {len(self.spec['headline'])} rows; expected at most 8")
        goals = shared()["task"]["goal"]
        for row in self.rows:
            if "label" not in row:
                goal = self.data[row["id"]].get("goal")
                if goal not in goals:
                    raise UsageError(f"{self.file.name}: row {row['id']!r}: no label; expected one (only a "
                                     f"fixed-goal row, goal {' or '.join(goals)}, goes without)")
                row["label"] = goals[goal]

    def definitions(self) -> str:
        """The shared definitions of RMSE, success, the checkpoints and the page's kinds of fixed goal, then the
        page's own, each a paragraph."""
        text, spec = shared()["task"], self.spec
        last = any("last weights" in row["label"] for row in self.rows)
        measures = slots(text["definitions"], {"grip": spec.get("grip", text["grip"]),
                                               "check": spec.get("check", text["check"]),
                                               "but": text["but"] if last else ""})
        goals = {self.data[row["id"]].get("goal") for row in self.rows}
        fixed = "; ".join(what for goal, what in text["fixed-goal"].items() if goal in goals)
        parts = [measures, slots(text["fixed"], {"goals": fixed}) if fixed else "", spec.get("definitions", "")]
        return "\n\n".join(self.fill(part) for part in parts if part.strip())

    def sets_note(self) -> str:
        return self.fill(" ".join([shared()["task"]["sets"].strip(), self.spec.get("sets_note", "").strip()]))

    def metrics(self, ref: str) -> tuple[str, list, list, str]:
        """(label, rmse per split, success per split, episodes) of a row id or of `paper:ROW`."""
        if ref.startswith("paper:"):
            key = ref.split(":", 1)[1]
            row = self.paper["rows"][key]
            demos = " / ".join(map(str, self.paper.get("demos", ())))
            return (f"{row_name(key)}, the paper", list(row.get("rmse", (None,) * 3)),
                    list(row["success"]), demos)
        row = next(r for r in self.rows if r["id"] == ref)
        d = self.data[ref]
        exact = d.get("goal") == "demo"  # the demo's own goal: zero RMSE by construction
        rmse = [None if exact or k not in d else d[k].get("rmse") for k in SPLITS]
        success = [d[k]["success_rate"] if k in d else None for k in SPLITS]
        episodes = " / ".join(str(d[k]["episodes"]) if k in d else "-" for k in SPLITS)
        return row["label"], rmse, success, episodes

    # -- tables ---------------------------------------------------------------------------------------------------
    def rate(self, ref: str, split: str, value) -> str:
        """A row's success on a split, as exact as its episodes allow; the paper's as it prints them."""
        d = None if ref.startswith("paper:") else self.data[ref].get(split)
        return split_rate(d) if d and d.get("episodes") else cell(value, "{:.2f}")

    def table(self, refs: list[str]) -> list[str]:
        lines = ["| | success train | success unseen | success ood | RMSE train | RMSE unseen | RMSE ood | episodes |",
                 "| --- | --- | --- | --- | --- | --- | --- | --- |"]
        for ref in refs:
            label, rmse, success, episodes = self.metrics(ref)
            lines.append(f"| {label} | " + " | ".join(self.rate(ref, k, v) for k, v in zip(SPLITS, success)) + " | "
                         + " | ".join(cell(v, "{:.3f}") for v in rmse) + f" | {episodes} |")
        return lines

    def full_refs(self, group: str) -> list[str]:
        refs, seen = [], set()
        for row in self.rows:
            if row.get("group", "tax3d") != group:
                continue
            refs.append(row["id"])
            key = row.get("paper")
            if key and key not in seen and key in self.paper["rows"]:
                refs.append(f"paper:{key}")
                seen.add(key)
        return refs

    def sets_table(self) -> list[str]:
        lines = ["| | coverage train | coverage unseen | coverage ood | precision train | precision unseen | "
                 "precision ood |", "| --- | --- | --- | --- | --- | --- | --- |"]
        seen = set()
        for row in self.rows:
            d = self.data[row["id"]]
            if d.get("goal") == "demo" or not any(d.get(k, {}).get("coverage_rmse") is not None for k in SPLITS):
                continue
            values = [d.get(k, {}).get(m) for m in ("coverage_rmse", "precision_rmse") for k in SPLITS]
            lines.append(f"| {row['label']} | " + " | ".join(cell(v, "{:.3f}") for v in values) + " |")
            key = row.get("paper")
            paper = self.paper["rows"].get(key, {}) if key else {}
            if "coverage" in paper and key not in seen:
                seen.add(key)
                lines.append(f"| {row_name(key)}, the paper | "
                             + " | ".join(f"{v:.3f}" for v in (*paper["coverage"], *paper["precision"])) + " |")
        return lines

    def curve_table(self) -> list[str]:
        by_step = [{p["step"]: p["val_rmse"] for p in self.data[c["id"]]["points"]} for c in self.curves]
        steps = sorted(set().union(*by_step))
        first = self.data[self.curves[0]["id"]]
        lines = [f"The best of {first['val_samples']} goal samples per demo, averaged over the first "
                 f"{first['val_demos']} demos of `{', '.join(first['val'])}`, as logged by `tax3d train`:", "",
                 "| step | " + " | ".join(c["label"] for c in self.curves) + " |",
                 "| --- |" + " --- |" * len(self.curves)]
        lines += [f"| {s:,} | " + " | ".join(cell(b.get(s), "{:.3f}") for b in by_step) + " |" for s in steps]
        return lines

    def commands(self) -> list[str]:
        lines = [f"- demonstrations: `{c}`" for c in self.spec.get("setup", [])]
        for row in self.rows:
            d = self.data[row["id"]]
            made = f" made by {shown(row['made'])}, then" if row.get("made") else ""
            if "checkpoint" in d:
                how = f"evaluated by {shown(d['command'])} (checkpoint `{d['checkpoint']}`)"
            else:
                offset = ", ".join(f"{v:g}" for v in d.get("offset", ()))
                how = shown(d["command"]) + (f" (gripper-target offset ({offset}))" if offset else "")
            config = f" Configuration: [{row['config']}]({row['config']})." if row.get("config") else ""
            config += f" Shipped as `{row['shipped']}`." if row.get("shipped") else ""
            lines.append(f"- **{row['label']}** ([{row['summary']}]({row['summary']})):{made} {how}, on "
                         f"{d['machine']}, {d['date']}.{config}")
        for c in self.curves:
            d = self.data[c["id"]]
            lines.append(f"- curve **{c['label']}** ([{c['summary']}]({c['summary']})): the run `{d['run']}`.")
        for s in self.spec.get("source", []):
            d = self.data[s["id"]]
            how = shown(d["command"]) if "command" in d else f"the run `{d['run']}`"  # a run's summary.json
            lines.append(f"- {s['label']} ([{s['summary']}]({s['summary']})): {how}, {d['date']}.")
        return lines

    def timings(self) -> list[str]:
        lines = ["| | split | prediction | simulation |", "| --- | --- | --- | --- |"]
        for row in self.rows:
            d = self.data[row["id"]]
            lines += [f"| {row['label']} | {k} | {d[k]['predict_seconds']:.2f} | {d[k]['sim_seconds']:.2f} |"
                      for k in SPLITS if k in d and d[k].get("sim_seconds") is not None]
        return lines

    def spread(self) -> list[str]:
        def rows(d: dict, named: list[tuple[str, str]]) -> list[str]:
            return ["| | " + " | ".join(SPLITS) + " |", "| --- |" + " --- |" * 3,
                    *[f"| {label} | " + " | ".join(f"{d[k][key]:.3f}" for k in SPLITS) + " |" for label, key in named],
                    ""]

        lines = []
        if "goal-spread" in self.data:
            lines += rows(self.data["goal-spread"], [
                ("mean goal of train in the anchor frame", "mean_goal_rmse"),
                ("the same, turned with the anchor's true rotation (an oracle)", "rotated_mean_goal_rmse")])
        if "mode-spread" in self.data:
            lines += rows(self.data["mode-spread"], [
                ("RMSE between a cloth's two goals", "goal_separation_rmse"),
                ("RMSE of their midpoint to either goal", "midpoint_rmse")])
        return lines

    # -- the page -------------------------------------------------------------------------------------------------
    def ledger(self) -> list[dict]:
        return ledger.read(self.root / "table" / "ledger.jsonl")

    def draws(self, rows: dict[int, dict[str, dict]]) -> dict[int, dict]:
        """The draw each table of the protocol names, checked against its rows."""
        draws = {}
        for draw in self.spec.get("draw", []):
            demos = draw.get("demos")
            if demos not in rows:
                raise UsageError(f"{self.file.name}: draw of {demos} demos: no table of that size; expected one of "
                                 f"{', '.join(map(str, sorted(rows)))}")
            draws[demos] = table.check_draw(self.file.name, demos, draw, rows[demos])
        return draws

    def protocol(self) -> list[str]:
        """The paper's table beside the rows of `tax3d table` (docs/results/table/TASK/), when there are any."""
        rows = table.load_rows(self.root / "table" / self.spec.get("task", ""))
        if not rows:
            return []
        lines = self.ledger()
        shipped = [f"the {row_name(key)} row at {demos} demos as [{checkpoint}](../../{checkpoint}/README.md)"
                   for path, checkpoint in shipped_rows(self.root, self.spec["task"])
                   for demos, key in [(int(Path(path).parent.name), paper_key(Path(path).stem))]]
        ship = [f"Shipped: {', '.join(shipped)}, each with its model card.", ""] if shipped else []
        return [table.verdict(self.paper, rows), "", "## The paper's table under one protocol", "",
                *table.markdown(self.spec["task"], self.paper, rows, lines, self.draws(rows)), *ship,
                *self.notes("table"), *fold("How each row was made", table.commands(rows, lines))]

    def markdown(self) -> str:
        spec = self.spec
        lines = [self.verdict(), "", *self.table(spec["headline"]), "",
                 f"![success per split]({self.name}.png)", "", self.definitions(), "", *self.notes(),
                 "## Every row", "", f"The paper's rows are from its {self.paper.get('table', 'tables')} "
                 "(docs/results/paper.toml).", "",
                 *fold(f"All {len(self.full_refs('tax3d'))} rows of TAX3D, its baselines and the fixed goals",
                       self.table(self.full_refs("tax3d")))]
        if any(r.get("group") == "ablation" for r in self.rows):
            lines += ["## Ablations", "", *fold("The ablations beside the paper's",
                                                 self.table(self.full_refs("ablation")))]
        if spec.get("sets"):
            lines += ["## Coverage and precision RMSE", "", self.sets_note(), "",
                      *fold("Coverage and precision RMSE of every row", self.sets_table())]
        if spec.get("spread_note"):
            title = spec.get("spread_title", "How far a fixed goal gets")
            lines += [f"## {title}", "", self.fill(spec["spread_note"]), "", *self.spread()]
        if self.curves:
            lines += ["## Validation RMSE over training", "", *fold("The validation curves", self.curve_table())]
        if spec.get("detail"):
            lines += ["## Notes", "", *self.details()]
        lines += ["## Commands", "", "The commands that made each row, the machine and the date. A `tax3d train "
                  "--preset cpu` command names every option in which the preset of its date differs from today's, "
                  "so it makes the same configuration today (`tests/test_made_commands.py` checks it for every row "
                  "whose configuration is kept); one that takes an option since retired, or names a command or a "
                  f"script since renamed or moved, is marked \"{EARLIER}\", with what runs it today:", "",
                  *fold("Every command", self.commands())]
        if len(self.timings()) > 2:
            lines += ["## Seconds per episode", "", *fold(
                "Mean prediction and simulation seconds per episode, per worker process, from the same evaluations "
                "(other jobs on the machine; `benchmarks/` has the quiet-machine figures)", self.timings())]
        protocol = self.protocol()
        if protocol:  # the table under one protocol heads the page; the earlier recipes' page folds below it
            scene = any(r.get("paper") in ("SD", "SP") for r in self.rows)
            lines = [*protocol, "## Earlier recipes", "", "Rows trained with earlier recipes, their weights and "
                     "settings chosen on the `unseen` and `ood` episodes demo_0-39; the table above replaces them row "
                     "by row." + (" Their SD and SP rows were scored while these variants were given the whole "
                                  "action cloud, whose mean moved their frame's origin from where training put it."
                                  if scene else ""), "", *fold("The earlier recipes' rows, notes and commands", lines)]
        return "\n".join([f"# {spec['title']}", "", *lines]).rstrip() + "\n"

    def plot(self) -> bytes:
        bars = [self.metrics(ref) for ref in self.spec["headline"]]
        return plots.success_bars([b[0] for b in bars], SPLITS, [b[2] for b in bars])

    def files(self) -> dict[Path, bytes]:
        return {self.root / f"{self.name}.md": self.markdown().encode(), self.root / f"{self.name}.png": self.plot()}

    def readme_row(self) -> str:
        best = self.spec["readme"]
        rows = table.load_rows(self.root / "table" / self.spec.get("task", ""))
        largest = next((rows[n]["CD"] for n in sorted(rows, reverse=True) if "CD" in rows[n]), None)
        if largest is not None:  # the table's protocol, from the row's own fields and its lines in the ledger
            theirs = " / ".join(f"{self.paper['rows']['CD']['success'][SPLITS.index(k)]:.2f}" for k in ("unseen", "ood"))
            ours = " / ".join(f"{split_rate(largest['splits'][k])} ({largest['splits'][k]['success_ci95'][0]:.2f}-"
                              f"{largest['splits'][k]['success_ci95'][1]:.2f})" for k in ("unseen", "ood"))
            scored = len(ledger.of_row(self.ledger(), largest["task"], largest["num_train"], largest["variant"]))
            chosen = ("weights chosen on `val`" if largest["weights_chosen_on"] == "val"
                      else f"weights: {largest['weights_chosen_on']}")
            label = (f"TAX3D-CD, {largest['num_train']} demos, `--preset {largest['preset']}`, "
                     f"{largest['minutes']:g}-minute plan; {chosen}, test scored {table.times(scored)}")
            return (f"| {best['task']} | {ours} ({label}) | {theirs} | "
                    f"[docs/results/{self.name}.md](docs/results/{self.name}.md) |")
        d, paper = self.data[best["row"]], self.paper["rows"][best["paper"]]
        ours = " / ".join(cell(d.get(k, {}).get("success_rate"), "{:.2f}") for k in ("unseen", "ood"))
        theirs = " / ".join(f"{paper['success'][SPLITS.index(k)]:.2f}" for k in ("unseen", "ood"))
        label = self.metrics(best["row"])[0]
        return (f"| {best['task']} | {ours} ({label}) | {theirs} | "
                f"[docs/results/{self.name}.md](docs/results/{self.name}.md) |")


def readme_table(pages: list[TaskPage]) -> str:
    """The README's results table: the `readme` row of each task page beside the paper's, in their `order`."""
    shown_pages = sorted((p for p in pages if p.spec.get("readme")), key=lambda p: p.spec["readme"]["order"])
    rows = [p.readme_row() for p in shown_pages]
    return "\n".join(["| task | our success, unseen / ood | the paper's | page |", "| --- | --- | --- | --- |", *rows])
