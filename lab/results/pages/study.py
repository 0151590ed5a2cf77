"""The time-to-quality study (`kind = "training"`): its section of docs/results/training.md, its plot, and the table of
docs/training.md that gives what each difference of the `cpu` preset from the paper's buys.

The declaration names the page it fills between `<!-- study -->` and `<!-- /study -->` (`page`), its plot (`plot`),
the study files (`studies`, a glob of kept lab.studies.time_to_quality JSON), the minutes of its table
(`marks`), the run of the shipped recipe (`shipped`, "STUDY: RUN"), the guide it fills between
`<!-- differences -->` and `<!-- /differences -->` (`guide`) and its rows (`difference`: what, with and without,
two "STUDY: RUN", optional with_eval and without_eval, kept evaluations of each run's weights).
"""

from __future__ import annotations

import itertools
import os
import re
from pathlib import Path

from tax3d.errors import UsageError
from lab.results import kept
from lab.results.commands import shown
from lab.results.pages import plots
from lab.results.pages.page import Page, fold

STUDY = ("<!-- study -->", "<!-- /study -->")
DIFFERENCES = ("<!-- differences -->", "<!-- /differences -->")


def fill_between(path: Path, markers: tuple[str, str], text: str) -> bytes:
    """The file at `path` with `text` between its two marker lines."""
    if not path.is_file():
        raise UsageError(f"{path}: not found; expected the page with {markers[0]} ... {markers[1]} lines to fill")
    page = path.read_text()
    if markers[0] not in page or markers[1] not in page:
        raise UsageError(f"{path}: no {markers[0]} ... {markers[1]} lines to fill")
    head, rest = page.split(markers[0], 1)
    _, tail = rest.split(markers[1], 1)
    return (head + markers[0] + "\n" + text + "\n" + markers[1] + tail).encode()


class StudyPage(Page):
    required = ("verdict", "page", "plot", "studies", "marks", "shipped")

    def __init__(self, *args):
        super().__init__(*args)
        pattern = self.spec["studies"]
        # in the order the studies were made: ttq-2 before ttq-10
        paths = sorted(self.root.glob(pattern), key=lambda p: [int(t) if t.isdigit() else t
                                                                for t in re.split(r"(\d+)", p.stem)])
        if not paths:
            raise UsageError(f"{self.file.name}: studies {pattern!r}: no file in {self.root}; expected the kept "
                             "`python -m lab.studies.time_to_quality` JSON")
        self.studies = [(p.stem, kept.load(p, ("study",)), p.relative_to(self.root).as_posix()) for p in paths]
        self.runs = {f"{name}: {run}": result for name, study, _ in self.studies
                     for run, result in study["runs"].items()}
        self.data["shipped"] = self._end(self.spec["shipped"], "shipped")
        first = self.studies[0][1]
        counts = sorted({len(r["curve"]) for r in self.runs.values()})
        self.data["study"] = {**first, "val_split": " ".join(first["val"]), "validations": str(counts[0]) if
                              len(counts) == 1 else f"{counts[0]} to {counts[-1]}"}
        self.evals = {}
        for d in self.spec.get("difference", []):
            for key in ("with_eval", "without_eval"):
                if key in d:
                    self.evals[d[key]] = kept.load(self.root / d[key], ("eval",))["splits"]

    def _end(self, label: str, what: str) -> dict:
        """The last validation of a run named "STUDY: RUN", with its label, steps and options."""
        if label not in self.runs or not self.runs[label]["curve"]:
            raise UsageError(f"{self.file.name}: {what} {label!r}: no such run with validations in "
                             f"{self.spec['studies']}; expected \"STUDY: RUN\"")
        run = self.runs[label]
        return {**run["curve"][-1], "label": label, "steps": run["steps"], "options": run["options"]}

    @staticmethod
    def at_minute(curve: list[dict], mark: float) -> dict | None:
        """The last validation at or before `mark` minutes, allowing 10% for a run slowed by other work."""
        before = [point for point in curve if point["minutes"] <= 1.1 * mark]
        return before[-1] if before else None

    def table(self) -> list[str]:
        def cell(point):
            return "-" if point is None else f"{point['val_rmse']:.3f} ({point['minutes']:.0f} min)"

        marks = self.spec["marks"]
        lines = ["| study | run | options added to the `cpu` preset of the time | "
                 + " | ".join(f"RMSE @ {m} min" for m in marks)
                 + " | at the end | steps / min (whole run) | steps / min (first steps) |",
                 "| --- | --- | --- | " + " | ".join("---" for _ in marks) + " | --- | --- | --- |"]
        for name, study, _ in self.studies:
            for run, result in study["runs"].items():
                curve, plan = result["curve"], result.get("plan")
                options = f"`{result['options']}`" if result["options"] else "(none)"
                lines.append(f"| {name} | {run} | {options} | "
                             + " | ".join(cell(self.at_minute(curve, m)) for m in marks)
                             + f" | {cell(curve[-1] if curve else None)} | {result['steps_per_minute']:.0f} | "
                             + (f"{60 / plan['step_seconds']:.0f}" if plan else "-") + " |")
        return lines

    def markdown(self) -> str:
        page, plot = (self.root / self.spec["page"]).resolve(), (self.root / self.spec["plot"]).resolve()
        link = os.path.relpath(plot, page.parent)
        commands = [f"- {label}: {shown(result['command'])}" for label, result in self.runs.items()]
        # consecutive studies made on the same machine and day share one mention of them
        measured = "; ".join(
            ", ".join(f"[{rel}]({os.path.relpath((self.root / rel).resolve(), page.parent)})" for _, _, rel in same)
            + f" on {machine}, {date}"
            for (machine, date), same in itertools.groupby(self.studies, lambda s: (s[1]["machine"], s[1]["date"])))
        lines = [self.verdict(), "", f"![validation RMSE against minutes]({link})", "",
                 f"Measured by `python -m lab.studies.time_to_quality`: {measured}; built by "
                 f"`python -m lab.results {self.name}`.", "",
                 *self.notes(), *fold(f"Every run of the {len(self.studies)} studies", self.table()),
                 *self.details("The study log: what each study found"), *fold("The command of each run", commands)]
        return "\n".join(lines).rstrip()

    def differences(self) -> str:
        """What each difference of the `cpu` preset from `paper` buys: the two runs at the end of equal plans."""
        def success(path: str | None) -> str:
            splits = self.evals.get(path) if path else None
            return "-" if splits is None else " / ".join(f"{splits[k]['success_rate']:.2f}" for k in ("unseen", "ood"))

        lines = ["| `cpu` instead of `paper` | validation RMSE, with / without | success unseen / ood, with against "
                 "without | the runs (study: run) |", "| --- | --- | --- | --- |"]
        for d in self.spec.get("difference", []):
            ends = [self._end(d[key], "difference") for key in ("with", "without")]
            rmse = " / ".join(f"{e['val_rmse']:.3f} ({e['minutes']:.0f} min)" for e in ends)
            scored = [success(d.get(key)) for key in ("with_eval", "without_eval")]
            lines.append(f"| {d['what']} | {rmse} | {' against '.join(scored) if scored != ['-', '-'] else '-'} | "
                         f"{d['with']}; {d['without']} |")
        return "\n".join(lines)

    def plot(self) -> bytes:
        runs = [(label, [p["minutes"] for p in r["curve"]], [p["val_rmse"] for p in r["curve"]])
                for label, r in self.runs.items()]
        floor = self.data["floor"]["rmse_mean_goal_baseline"] if "floor" in self.data else None
        return plots.validation_curves(runs, floor, f"validation RMSE ({self.data['study']['val_demos']} unseen demos)")

    def files(self) -> dict[Path, bytes]:
        out = {(self.root / self.spec["page"]).resolve(): fill_between((self.root / self.spec["page"]).resolve(),
                                                                        STUDY, self.markdown()),
               (self.root / self.spec["plot"]).resolve(): self.plot()}
        if "guide" in self.spec:
            guide = (self.root / self.spec["guide"]).resolve()
            out[guide] = fill_between(guide, DIFFERENCES, self.differences())
        return out
