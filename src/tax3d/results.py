"""`tax3d results`: build the result pages of docs/results/ from their declarations and the kept summaries.

Each page is a TOML file in docs/results/pages/: its rows (label, the kept JSON it reads, the commands that made
it), the paper's rows it sets beside them (docs/results/paper.toml) and its notes, markdown in which every number
is a `{source.key.key}` placeholder filled from a kept JSON. The README's results table is built from the same
declarations, between `<!-- results -->` and `<!-- /results -->`. A declaration with a `kind` (sim, official,
training) is a measurement page instead, built by tax3d.results_pages.

A declaration holds `title`, `task` (its key in paper.toml), `verdict`, `definitions`, `headline` (at most 8 row
ids or `paper:ROW`), optional `readme`, `setup`, `sets`, `sets_note`, `spread_note`, and arrays of tables: `row`
(id, label, summary, optional paper, group = "ablation", made, config, shipped), `curve`, `source` (other kept
JSON the notes cite), `note` and `ablation_note` (title, text, optional fold). `{id.split.metric}` reads a row's split
(`success` for success_rate), `{id.key.key}` any key of a kept JSON, `{paper.ROW.metric.split}` the paper's table;
`{...:.3f}` formats.
"""

from __future__ import annotations

import io
import json
import re
import sys
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Optional

import tyro

from tax3d import table
from tax3d.atomic import write_bytes
from tax3d.commands import EARLIER, shown
from tax3d.errors import UsageError

ROOT = Path(__file__).resolve().parents[2]
SPLITS = ("train", "unseen", "ood")
VARIANT_NAMES = {"CD": "TAX3D-CD", "CP": "TAX3D-CP"}
ALIASES = {"success": "success_rate"}
PLACEHOLDER = re.compile(r"\{([A-Za-z][\w-]*(?:\.[\w-]+)+)(?::([^{}]+))?\}")
MARKERS = ("<!-- results -->", "<!-- /results -->")


@dataclass
class Args:
    """Build the result pages of docs/results/ (and the README's results table, docs/training.md's study) from
    docs/results/pages/*.toml."""

    page: tyro.conf.Positional[Optional[str]] = None
    """one page, by its name (e.g. hangbag); default: every page"""
    check: bool = False
    """build in memory and exit 1, naming each page that differs from the one on disk"""
    root: Optional[str] = None
    """the results folder (default: docs/results of this checkout)"""


def _fmt(key: str, value) -> str:
    if isinstance(value, list):
        return "(" + ", ".join(f"{v:g}" for v in value) + ")"
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return str(value)
    if isinstance(value, int):
        return f"{value:,}"
    return f"{value:.2f}"


def _cell(value, fmt: str) -> str:
    return "-" if value is None else fmt.format(value)



def retired(d: dict) -> str:
    """For a kept summary made by a script that has since become a `tax3d` option: the command to use today."""
    if d["command"].startswith("python scripts/oracle_policy.py"):
        return f" (today: `tax3d eval --goal {d.get('goal', 'demo')}` with the same options)"
    if d["command"].startswith("python scripts/sampler_check.py"):
        return " (today: `python benchmarks/samplers.py`, one checkpoint at a time)"
    return ""

class Page:
    """One page's declaration with its sources loaded."""

    def __init__(self, file: Path, root: Path, paper: dict):
        self.file, self.root, self.name = file, root, file.stem
        try:
            self.spec = tomllib.loads(file.read_text())
        except tomllib.TOMLDecodeError as err:
            raise UsageError(f"{file}: not valid TOML ({err})") from None
        self.paper_all, self.paper = paper, paper.get(self.spec.get("task", ""), {"rows": {}})
        if len(self.spec.get("headline", ())) > 8:
            raise UsageError(f"{file.name}: headline has {len(self.spec['headline'])} rows; expected at most 8")
        self.rows = self.spec.get("row", [])
        self.curves = self.spec.get("curve", [])
        self.data = {}
        for kind, items in (("row", self.rows), ("curve", self.curves), ("source", self.spec.get("source", []))):
            for item in items:
                self.data[item["id"]] = self._load(kind, item)

    def _load(self, kind: str, item: dict) -> dict:
        path = self.root / item["summary"]
        if not path.is_file():
            raise UsageError(f"{self.file.name}: {kind} {item['id']!r} ({item.get('label', '')}): "
                             f"{path} not found; expected a kept summary")
        data = json.loads(path.read_text())
        if "summary" in data:  # `tax3d eval`'s results.json, kept by scripts/keep_summary.py
            data = data["summary"]
        if "points" in data:  # a validation curve kept by scripts/val_curve.py
            best = min(data["points"], key=lambda p: p["val_rmse"])
            data = {**data, "best_step": best["step"], "best_rmse": best["val_rmse"],
                    "last_step": data["points"][-1]["step"]}
        if "config" in item:
            data = {**data, "config": json.loads((self.root / item["config"]).read_text())}
        return {**data, **data.get("splits", {})}

    # -- values ---------------------------------------------------------------------------------------------------
    def value(self, path: str):
        keys = path.split(".")
        if keys[0] != "paper":
            keys = [ALIASES.get(k, k) for k in keys]
        elif keys[1] in self.paper["rows"]:  # paper.ROW.metric.split
            return self.paper["rows"][keys[1]][keys[2]][SPLITS.index(keys[3])]
        node = self.paper_all if keys[0] == "paper" else self.data[keys[0]]
        for k in keys[1:]:
            node = node[int(k)] if isinstance(node, list) else node[k]
        return node

    def fill(self, text: str) -> str:
        def sub(m: re.Match) -> str:
            try:
                value = self.value(m.group(1))
            except (KeyError, IndexError, ValueError):
                raise UsageError(f"{self.file.name}: placeholder {m.group(0)}: no such value in the kept "
                                 "summaries") from None
            return format(value, m.group(2)) if m.group(2) else _fmt(m.group(1).rsplit(".", 1)[-1], value)
        return PLACEHOLDER.sub(sub, text.strip())

    def metrics(self, ref: str) -> tuple[str, list, list, str]:
        """(label, rmse per split, success per split, episodes) of a row id or of `paper:ROW`."""
        if ref.startswith("paper:"):
            key = ref.split(":", 1)[1]
            row = self.paper["rows"][key]
            demos = " / ".join(map(str, self.paper.get("demos", ())))
            return (f"{VARIANT_NAMES.get(key, key)}, the paper", list(row.get("rmse", (None,) * 3)),
                    list(row["success"]), demos)
        row = next(r for r in self.rows if r["id"] == ref)
        d = self.data[ref]
        exact = d.get("goal") == "demo"  # the demo's own goal: zero RMSE by construction
        rmse = [None if exact or k not in d else d[k].get("rmse") for k in SPLITS]
        success = [d[k]["success_rate"] if k in d else None for k in SPLITS]
        episodes = " / ".join(str(d[k]["episodes"]) if k in d else "-" for k in SPLITS)
        return row["label"], rmse, success, episodes

    # -- sections -------------------------------------------------------------------------------------------------
    def table(self, refs: list[str]) -> list[str]:
        lines = ["| | success train | success unseen | success ood | RMSE train | RMSE unseen | RMSE ood | episodes |",
                 "| --- | --- | --- | --- | --- | --- | --- | --- |"]
        for ref in refs:
            label, rmse, success, episodes = self.metrics(ref)
            lines.append(f"| {label} | " + " | ".join(_cell(v, "{:.2f}") for v in success) + " | "
                         + " | ".join(_cell(v, "{:.3f}") for v in rmse) + f" | {episodes} |")
        return lines

    def full_refs(self, group: str) -> list[str]:
        refs, shown = [], set()
        for row in self.rows:
            if row.get("group", "tax3d") != group:
                continue
            refs.append(row["id"])
            key = row.get("paper")
            if key and key not in shown and key in self.paper["rows"]:
                refs.append(f"paper:{key}")
                shown.add(key)
        return refs

    def sets_table(self) -> list[str]:
        lines = ["| | coverage train | coverage unseen | coverage ood | precision train | precision unseen | "
                 "precision ood |", "| --- | --- | --- | --- | --- | --- | --- |"]
        shown = set()
        for row in self.rows:
            d = self.data[row["id"]]
            if d.get("goal") == "demo" or not any(d.get(k, {}).get("coverage_rmse") is not None for k in SPLITS):
                continue
            values = [d.get(k, {}).get(m) for m in ("coverage_rmse", "precision_rmse") for k in SPLITS]
            lines.append(f"| {row['label']} | " + " | ".join(_cell(v, "{:.3f}") for v in values) + " |")
            key = row.get("paper")
            paper = self.paper["rows"].get(key, {}) if key else {}
            if "coverage" in paper and key not in shown:
                shown.add(key)
                lines.append(f"| {VARIANT_NAMES.get(key, key)}, the paper | "
                             + " | ".join(f"{v:.3f}" for v in (*paper["coverage"], *paper["precision"])) + " |")
        return lines

    def curve_table(self) -> list[str]:
        by_step = [{p["step"]: p["val_rmse"] for p in self.data[c["id"]]["points"]} for c in self.curves]
        steps = sorted(set().union(*by_step))
        first = self.data[self.curves[0]["id"]]
        lines = [f"The best of {first['val_samples']} goal samples per demo, averaged over the first "
                 f"{first['val_demos']} demos of `{', '.join(first['val'])}`, as logged by `tax3d train` (kept by "
                 "`scripts/val_curve.py`):", "",
                 "| step | " + " | ".join(c["label"] for c in self.curves) + " |",
                 "| --- |" + " --- |" * len(self.curves)]
        lines += [f"| {s:,} | " + " | ".join(_cell(b.get(s), "{:.3f}") for b in by_step) + " |" for s in steps]
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
                how += retired(d)
            config = f" Configuration: [{row['config']}]({row['config']})." if row.get("config") else ""
            config += f" Shipped as `{row['shipped']}`." if row.get("shipped") else ""
            lines.append(f"- **{row['label']}** ([{row['summary']}]({row['summary']})):{made} {how}, on "
                         f"{d['machine']}, {d['date']}.{config}")
        for c in self.curves:
            d = self.data[c["id"]]
            lines.append(f"- curve **{c['label']}** ([{c['summary']}]({c['summary']})): the run `{d['run']}`.")
        for s in self.spec.get("source", []):
            d = self.data[s["id"]]
            lines.append(f"- {s['label']} ([{s['summary']}]({s['summary']})): {shown(d['command'])}{retired(d)}, "
                         f"{d['date']}.")
        return lines

    def timings(self) -> list[str]:
        lines = ["| | split | prediction | simulation |", "| --- | --- | --- | --- |"]
        for row in self.rows:
            d = self.data[row["id"]]
            lines += [f"| {row['label']} | {k} | {d[k]['predict_seconds']:.2f} | {d[k]['sim_seconds']:.2f} |"
                      for k in SPLITS if k in d and d[k].get("sim_seconds") is not None]
        return lines

    def spread(self) -> list[str]:
        def table(d: dict, rows: list[tuple[str, str]]) -> list[str]:
            return ["| | " + " | ".join(SPLITS) + " |", "| --- |" + " --- |" * 3,
                    *[f"| {label} | " + " | ".join(f"{d[k][key]:.3f}" for k in SPLITS) + " |" for label, key in rows],
                    ""]

        lines = []
        if "goal-spread" in self.data:
            lines += table(self.data["goal-spread"], [
                ("mean goal of train in the anchor frame", "mean_goal_rmse"),
                ("the same, turned with the anchor's true rotation (an oracle)", "rotated_mean_goal_rmse")])
        if "mode-spread" in self.data:
            lines += table(self.data["mode-spread"], [
                ("RMSE between a cloth's two goals", "goal_separation_rmse"),
                ("RMSE of their midpoint to either goal", "midpoint_rmse")])
        return lines

    # -- the page -------------------------------------------------------------------------------------------------
    def protocol(self) -> list[str]:
        """The paper's table beside the rows of `tax3d benchmark` (docs/results/table/TASK/), when there are any."""
        rows = table.load_rows(self.root / "table" / self.spec.get("task", ""))
        if not rows:
            return []
        return ["## The paper's table under one protocol", "", *table.markdown(self.spec["task"], self.paper, rows),
                *fold("How each row was made", table.commands(rows)),
                "## Earlier rows", "", "The rows below were trained with earlier recipes, their weights and settings "
                "chosen on the `unseen` and `ood` episodes demo_0-39; the table above replaces them row by row.", ""]

    def markdown(self) -> str:
        spec = self.spec
        lines = [f"# {spec['title']}", "", *self.protocol(), self.fill(spec["verdict"]), "",
                 *self.table(spec["headline"]), "",
                 f"![success per split]({self.name}.png)", "", self.fill(spec["definitions"]), ""]
        for note in spec.get("note", []):
            lines += self.section(note)
        lines += ["## Every row", "", f"The paper's rows are from its {self.paper.get('table', 'tables')} "
                  "(docs/results/paper.toml).", "",
                  *fold(f"All {len(self.full_refs('tax3d'))} rows of TAX3D, its baselines and the fixed goals",
                        self.table(self.full_refs("tax3d")))]
        if any(r.get("group") == "ablation" for r in self.rows):
            lines += ["## Ablations", "", *fold("The ablations beside the paper's",
                                                 self.table(self.full_refs("ablation")))]
            lines += [line for note in spec.get("ablation_note", []) for line in self.section(note, heading=False)]
        if spec.get("sets"):
            lines += ["## Coverage and precision RMSE", "", self.fill(spec["sets_note"]), "",
                      *fold("Coverage and precision RMSE of every row", self.sets_table())]
        if self.spec.get("spread_note"):
            title = spec.get("spread_title", "How far a fixed goal gets")
            lines += [f"## {title}", "", self.fill(spec["spread_note"]), "", *self.spread()]
        if self.curves:
            lines += ["## Validation RMSE over training", "", *fold("The validation curves", self.curve_table())]
        lines += ["## Commands", "", "The commands that made each row, the machine and the date. A `tax3d train "
                  "--preset cpu` command names every option in which the preset of its date differs from today's, "
                  "so it makes the same configuration today (`tests/test_made_commands.py` checks it for every row "
                  "whose configuration is kept); one that takes an option since retired is marked "
                  f"\"{EARLIER}\":", "",
                  *fold("Every command", self.commands())]
        if len(self.timings()) > 2:
            lines += ["## Seconds per episode", "", *fold(
                "Mean prediction and simulation seconds per episode, per worker process, from the same evaluations "
                "(other jobs on the machine; `benchmarks/` has the quiet-machine figures)", self.timings())]
        return "\n".join(lines).rstrip() + "\n"

    def section(self, note: dict, heading: bool = True) -> list[str]:
        body = self.fill(note["text"])
        if note.get("fold"):
            return fold(note["title"], [body])
        return ([f"**{note['title']}.** {body}"] if heading else [body]) + [""]

    def plot(self) -> bytes:
        """Grouped bars of success per split, one group per headline row; PNG bytes, the same on every run."""
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure

        bars = [self.metrics(ref) for ref in self.spec["headline"]]
        fig = Figure(figsize=(max(6.0, 0.8 * len(bars) + 2), 4.8))
        FigureCanvasAgg(fig)
        ax = fig.add_subplot()
        width = 0.27
        for j, split in enumerate(SPLITS):
            values = [0.0 if b[2][j] is None else b[2][j] for b in bars]
            ax.bar([i + (j - 1) * width for i in range(len(bars))], values, width, label=split)
        ax.set_xticks(range(len(bars)), [b[0] for b in bars], rotation=30, ha="right", fontsize=7)
        ax.set_ylim(0, 1.22)
        ax.set_ylabel("success rate")
        ax.legend(fontsize=7, ncols=3, loc="upper center")
        fig.tight_layout()
        out = io.BytesIO()
        fig.savefig(out, dpi=110, format="png", metadata={"Software": None})
        return out.getvalue()

    def files(self) -> dict[Path, bytes]:
        return {self.root / f"{self.name}.md": self.markdown().encode(), self.root / f"{self.name}.png": self.plot()}

    def readme_row(self) -> str:
        best = self.spec["readme"]
        d, paper = self.data[best["row"]], self.paper["rows"][best["paper"]]
        ours = " / ".join(_cell(d.get(k, {}).get("success_rate"), "{:.2f}") for k in ("unseen", "ood"))
        theirs = " / ".join(f"{paper['success'][SPLITS.index(k)]:.2f}" for k in ("unseen", "ood"))
        label = self.metrics(best["row"])[0]
        return (f"| {best['task']} | {ours} ({label}) | {theirs} | "
                f"[docs/results/{self.name}.md](docs/results/{self.name}.md) |")


def fold(summary: str, lines: list[str]) -> list[str]:
    return [f"<details><summary>{summary}</summary>", "", *lines, "", "</details>", ""]


def readme_table(pages: list[Page]) -> str:
    pages = sorted((p for p in pages if p.spec.get("readme") and p.spec.get("kind", "task") == "task"),
                   key=lambda p: p.spec["readme"]["order"])
    rows = [p.readme_row() for p in pages]
    return "\n".join(["| task | our success, unseen / ood | the paper's | page |", "| --- | --- | --- | --- |",
                      *rows])


def with_table(readme: str, table: str) -> str:
    start, end = readme.index(MARKERS[0]) + len(MARKERS[0]), readme.index(MARKERS[1])
    return readme[:start] + "\n" + table + "\n" + readme[end:]


def build(root: Path, only: str | None = None) -> dict[Path, bytes]:
    """Every file the pages of `root` make (markdown, plot, and the README's table), by path."""
    paper = tomllib.loads((root / "paper.toml").read_text())
    files = sorted((root / "pages").glob("*.toml"))
    names = [f.stem for f in files]
    if only is not None and only not in names:
        raise UsageError(f"page {only!r}: expected one of {', '.join(names)}")
    from tax3d.results_pages import KINDS

    out, pages = {}, []
    for f in files:
        if only in (None, f.stem):
            try:
                kind = tomllib.loads(f.read_text()).get("kind", "task")
            except tomllib.TOMLDecodeError as err:
                raise UsageError(f"{f}: not valid TOML ({err})") from None
            if kind != "task" and kind not in KINDS:
                raise UsageError(f"{f.name}: kind {kind!r}: expected task, {', '.join(KINDS)}")
            pages.append(KINDS.get(kind, Page)(f, root, paper))
            out.update(pages[-1].files())
    readme = root.parent.parent / "README.md"
    if only is None and readme.is_file() and MARKERS[0] in readme.read_text():
        out[readme] = with_table(readme.read_text(), readme_table(pages)).encode()
    return out


def run(args: Args) -> int:
    root = Path(args.root) if args.root else ROOT / "docs" / "results"
    if not (root / "paper.toml").is_file():
        raise UsageError(f"--root {root}: expected a results folder with paper.toml and pages/")
    files = build(root, args.page)
    if args.check:
        stale = [p for p, data in files.items() if not p.is_file() or p.read_bytes() != data]
        for p in stale:
            print(f"tax3d results: {p} differs from what `tax3d results` builds", file=sys.stderr)
        return 1 if stale else 0
    for path, data in files.items():
        write_bytes(path, data)
        print(path)
    return 0
