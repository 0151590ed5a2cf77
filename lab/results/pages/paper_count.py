"""The study at the paper's demonstration count (`kind = "paper-count"`): validation curves of TAX3D-CD arms trained
side by side far past the table's hour, kept by lab.studies.paper_count, against samples seen.

The declaration holds `page` (the markdown it writes), `verdict`, and `study` tables: id, label, summary (a kept
paper-count JSON), plot (the PNG it draws), optional `row` (a kept table row of the same task and count: its
samples are marked on the plot), `floor` (a kept `tax3d predict --baseline` summary on the same val demos) and
`evals` (kept `tax3d eval --splits val` summaries of an arm's kept steps, named ARM-STEP.json in one folder).
`{id.arms.ARM.best.KEY}` and `{id.arms.ARM.end.KEY}` read an arm's lowest and last validation.
"""

from __future__ import annotations

import os
from pathlib import Path

from tax3d import config as cfg
from tax3d.errors import UsageError
from tax3d.metrics import split_rate
from lab.results import kept
from lab.results.commands import shown
from lab.results.pages import plots
from lab.results.pages.page import Page, fold

METRIC = "val_rmse_mean"  # one sample a demo, as the policy acts


def paper_samples() -> int:
    """The paper's training samples (App. B.2: its steps at its batch)."""
    paper = cfg.paper().train
    return paper.steps * paper.batch_size


class PaperCountPage(Page):
    required = ("title", "verdict", "page", "study")

    def __init__(self, *args):
        super().__init__(*args)
        self.studies = []
        for study in self.spec["study"]:
            path = self.root / study["summary"]
            if not path.is_file():
                raise UsageError(f"{self.file.name}: study {study['id']!r}: {path} not found; expected the kept "
                                 "`python -m lab.studies.paper_count` JSON")
            data = kept.load(path, ("paper-count",))
            for name, arm in data["arms"].items():
                if not arm["curve"]:
                    raise UsageError(f"{path}: arm {name!r} has no validation yet; expected one at least")
                arm["best"] = min(arm["curve"], key=lambda p: p[METRIC])
                arm["end"] = arm["curve"][-1]
                arm["evals"] = self._evals(study, name)
            row = kept.load(self.root / study["row"], ("table-row",)) if "row" in study else None
            if "floor" in study:
                data["floor"] = kept.load(self.root / study["floor"], ("predict",))
            data["paper_samples"] = paper_samples()
            self.data[study["id"]] = data
            self.studies.append((study, data, row))

    def _evals(self, study: dict, arm: str) -> dict[int, dict]:
        """Kept `val` evaluations of an arm's kept steps, by step."""
        folder = self.root / study["evals"] if "evals" in study else None
        if folder is None or not folder.is_dir():
            return {}
        found = {}
        for path in sorted(folder.glob(f"{arm}-*.json")):
            step = path.stem[len(arm) + 1:]
            if step.isdigit():
                found[int(step)] = kept.load(path, ("eval",))["splits"]["val"]
        return found

    def table(self, data: dict) -> list[str]:
        lines = ["| arm | options on `--preset " + data["preset"] + "` | samples seen (wall hours) | lowest val "
                 "RMSE (at samples) | last val RMSE | last training loss | policy success on `val`, 95% interval (at step) |",
                 "| --- | --- | --- | --- | --- | --- | --- |"]
        for name, arm in data["arms"].items():
            best, end = arm["best"], arm["end"]
            policy = "; ".join(f"{split_rate(e)} ({e['success_ci95'][0]:.2f}-{e['success_ci95'][1]:.2f}) of "
                               f"{e['episodes']} at {step:,}" for step, e in sorted(arm["evals"].items()))
            lines.append(f"| {name} | `{arm['options'] or '(none)'}` | {end['samples']:,} ({end['hours']:.1f}) | "
                         f"{best[METRIC]:.3f} ({best['samples']:,}) | {end[METRIC]:.3f} | {end['train_mse']:.4f} | "
                         f"{policy or 'not scored yet'} |")
        return lines

    def plot(self, study: dict, data: dict, row: dict | None) -> bytes:
        runs = [(name, [p["samples"] for p in arm["curve"]], [p[METRIC] for p in arm["curve"]])
                for name, arm in data["arms"].items()]
        marks = [("the paper's budget", float(paper_samples()))]
        if row is not None:
            marks.append((f"the table's {row['minutes']:g}-minute row",
                          float(row["last_step"] * row["config"]["train"]["batch_size"])))
        floor = data["floor"]["rmse_mean_goal_baseline"] if "floor" in data else None
        return plots.sample_curves(runs, marks, floor, f"validation RMSE, one sample ({data['val_demos']} val demos)")

    def markdown(self) -> str:
        page = (self.root / self.spec["page"]).resolve()
        lines = [f"# {self.spec['title']}", "", self.verdict(), "", *self.notes()]
        for study, data, row in self.studies:
            link = os.path.relpath((self.root / study["plot"]).resolve(), page.parent)
            lines += [f"## {study['label']}", "", f"![validation RMSE against samples seen]({link})", "",
                      *self.table(data), "",
                      f"Each arm `tax3d train` on {data['num_train']} demos of `{data['train']}` (digest "
                      f"`{data['digests']['train'][:8]}`), validated on the first {data['val_demos']} of "
                      f"`{data['val']}` (`{data['digests']['val'][:8]}`), one core an arm, the arms side by side: "
                      f"{shown(data['command'])} on {data['machine']}, {data['date']}; built by "
                      f"`python -m lab.results {self.name}`.", "",
                      *fold("The command of each arm", [f"- {name}: {shown(arm['command'])}"
                                                        for name, arm in data["arms"].items()])]
        lines += self.details()
        return "\n".join(lines).rstrip() + "\n"

    def files(self) -> dict[Path, bytes]:
        out = {(self.root / self.spec["page"]).resolve(): self.markdown().encode()}
        for study, data, row in self.studies:
            out[(self.root / study["plot"]).resolve()] = self.plot(study, data, row)
        return out
