"""The model card of each shipped checkpoint (`kind = "cards"`): CHECKPOINT/README.md, from the checkpoint's
config.json, its kept evaluation and training log and the paper's table; no number typed by hand.

Each `card` of the declaration holds `checkpoint` (a folder, relative to the repository) and either `row` (the
table row whose weights it ships, as `tax3d table --keep` wrote it: its test episodes, how its weights were chosen
and the one command that made it) or `eval` (its kept `tax3d
eval` summary), optional `log` (its kept `tax3d train` log; left out for a run whose log was not kept: the card says
so), optional `official` (the RMSE on the authors' `val` split, for a checkpoint trained on their demonstrations),
and the commands that made its data and its weights (`data`, `train`).
"""

from __future__ import annotations

import tomllib
from pathlib import Path

from tax3d.eval import ledger
from tax3d.errors import UsageError
from tax3d.metrics import split_rate
from tax3d.variants import FIXED_GOALS, display_name, paper_key, row_name
from lab.results import kept
from lab.results.commands import renamed, shown
from lab.results.pages.page import SPLITS, Page, cell
from lab.results.table import times


CARDS = Path("pages") / "model-cards.toml"


def shipped_rows(root: Path, task: str) -> list[tuple[str, str]]:
    """(row file, checkpoint) of each card that ships a row of TASK's table; ROOT is docs/results/."""
    path = root / CARDS
    cards = tomllib.loads(path.read_text()).get("card", []) if path.is_file() else []
    return [(c["row"], c["checkpoint"]) for c in cards if c.get("row", "").startswith(f"table/{task}/")]


def success_table(splits: dict, paper: dict | None) -> list[str]:
    lines = ["| split | episodes | success | paper success | goal RMSE | paper RMSE | coverage RMSE |",
             "| --- | --- | --- | --- | --- | --- | --- |"]
    for name, split in splits.items():
        column = SPLITS.index(name) if name in SPLITS else None
        paper_success = paper["success"][column] if paper and column is not None else None
        paper_rmse = paper["rmse"][column] if paper and column is not None and "rmse" in paper else None
        lines.append(f"| {name} | {split['episodes']} | {split_rate(split)} | {cell(paper_success, '{:.2f}')} "
                     f"| {cell(split.get('rmse'), '{:.3f}')} | {cell(paper_rmse, '{:.3f}')} "
                     f"| {cell(split.get('coverage_rmse'), '{:.3f}')} |")
    return lines


def run_lines(config: dict, records: list[dict], plan: dict | None) -> list[str]:
    """Steps and wall time from the run's log; from its configuration alone when the log was not kept."""
    threads = config["train"].get("threads", 0)
    where = ("a GPU" if config["train"].get("device") == "cuda" else "one core" if threads == 1
             else f"{threads} threads" if threads else "torch's default threads")
    if not records:
        limit = config["train"].get("time_limit", 0)  # kept by earlier versions, which had train.time_limit
        return [f"- steps: a {config['train']['steps']:,}-step schedule" +
                (f", cut by a {limit:g}-minute limit" if limit else "") +
                f" on {where}; the run's log was not kept, so its steps done and validation curve are not known"]
    last = records[-1]
    return [f"- steps: {last['step']}" + (f" (planned for {plan['minutes']:g} minutes)" if plan else ""),
            f"- wall time: {last['seconds'] / 60:.0f} minutes on {where}"]


def official_lines(report: dict, paper: dict | None) -> list[str]:
    """The RMSE on the authors' `val` split, beside the paper's `unseen` RMSE and the mean-goal floor."""
    lines = ["", f"On the authors' `val` split ({report['demos']} demos, {report['samples']} samples each, "
             f"{report['date']}, {report['machine']}), the RMSE of the predicted goal:", "",
             "| predictor | RMSE | min over the samples |", "| --- | --- | --- |"]
    for name, result in report["samplers"].items():
        steps, sampler = name.split("_")[1], name.split("_")[0].upper()
        lines.append(f"| this checkpoint, {steps}-step {sampler} | {result['rmse']:.3f} | "
                     f"{result['rmse_min_of_samples']:.3f} |")
    if paper and "rmse" in paper:
        lines.append(f"| the paper (`unseen`) | {paper['rmse'][SPLITS.index('unseen')]:.3f} | - |")
    lines += [f"| mean goal of `train` (the floor) | {report['mean_goal_baseline_rmse']:.3f} | - |", "",
              f"Command: {shown(report['command'])}"]
    return lines


def card(checkpoint: str, config: dict, records: list[dict], summary: dict, data_command: str, train_command: str,
         paper_tables: dict, official: dict | None = None) -> str:
    plan = next((r["plan"] for r in records if "plan" in r), None)
    vals = [r for r in records if "val_rmse" in r]
    best = min(vals, key=lambda r: r["val_rmse"]) if vals else None
    task, variant = config["data"]["task"], config["model"]["variant"]
    paper = paper_tables.get(task, {}).get("rows", {}).get(variant.upper())
    source = "the authors' demonstrations" if official else "this project's own demonstrations"
    lines = [
        f"# {display_name(variant)} for {task}",
        "",
        f"A {display_name(variant)} goal predictor (a diffusion transformer over per-point cross-displacements) for "
        f"`{task}`, trained on {source} with the `cpu` recipe of [docs/training.md](../../docs/training.md).",
        *usage(checkpoint),
        f"`tax3d eval` on {summary['task']}, {summary['date']}, {summary['machine']}; the paper's figures from "
        f"its appendix D (docs/results/paper.toml):",
        "",
        *success_table(summary["splits"], paper),
        "",
        f"Command: {shown(summary['command'])}",
        *(official_lines(official, paper) if official else []),
        "",
        "## Training",
        "",
        network_line(config),
        "- training demonstrations: " + ", ".join(f"`{folder}`" for folder in config["data"]["train"])
        + " (made by the first command below)",
        *run_lines(config, records, plan),
    ]
    if best is not None and Path(summary.get("checkpoint") or "").name == "last" and vals[-1] is not best:
        lines.append(f"- last validation RMSE: {vals[-1]['val_rmse']:.3f} at step {vals[-1]['step']} (these weights, "
                     f"the run's last); lowest: {best['val_rmse']:.3f} at step {best['step']}")
    elif best is not None:
        lines.append(f"- best validation RMSE: {best['val_rmse']:.3f} at step {best['step']} (these weights)")
    lines += [
        "",
        "```bash",
        data_command,
        train_command,
        "```",
        "",
        *limits(task, config),
    ]
    return "\n".join(lines)


def usage(checkpoint: str) -> list[str]:
    """How to load the checkpoint and predict, then the results heading."""
    return ["", "```python", "from tax3d import Tax3D", f'model = Tax3D.from_pretrained("{checkpoint}")',
            "goals = model.predict(action_points, anchor_points, num_samples=5)  # (5, N, 3), world frame", "```",
            "", "## Results", ""]


def limits(task: str, config: dict) -> list[str]:
    return [
        "## Intended use and limits",
        "",
        f"- For research on relative placement of deformables in the simulated `{task}` scenes; the inputs are "
        "world-frame point clouds of the action object and of the anchor, in the benchmark's units.",
        ("- Trained with the anchor turned about z at random (rotation augmentation); the success above is "
         "measured in simulation only." if config["data"].get("rotate") else
         "- Trained without rotation augmentation: anchor poses far outside the training range are out of its "
         "reach, and the success above is measured in simulation only."),
        "- A CPU-budget model: see the table against the paper's before relying on it.",
        "",
    ]


def network_line(config: dict) -> str:
    return (f"- network: hidden {config['model']['hidden_size']}, depth {config['model']['depth']}; loss "
            f"`{config['diffusion'].get('loss', 'epsilon')}`, prediction `{config['diffusion']['prediction']}`, "
            f"sampler {config['diffusion']['sample_steps']}-step {config['diffusion']['sampler'].upper()}"
            + (f"; the grasped vertices weigh {config['data']['grip_weight']:g} in the loss"
               if config["data"].get("grip_weight", 1.0) != 1.0 else ""))


def bounds_line(row: dict, bounds: dict[str, dict]) -> list[str]:
    """One sentence on what the policy hangs on the same test episodes with the floor's and the ceiling's goals."""
    said = []
    for key in FIXED_GOALS:
        if key in bounds:
            what = ("the " if key == "floor" else "") + row_name(key)  # "each demo's own goal" takes none
            rates = " / ".join(split_rate(bounds[key]["splits"][split]) for split in row["splits"])
            said.append(f"{what} hangs {rates}")
    return [f"On the same episodes ({' / '.join(row['splits'])}), {' and '.join(said)}.", ""] if said else []


def row_card(checkpoint: str, config: dict, row: dict, paper_task: dict, bounds: dict[str, dict] | None = None,
             scorings: int | None = None) -> str:
    """The card of weights shipped from a table row: its test episodes scored once, chosen on `val`, one command;
    `bounds` the floor and ceiling rows of the same table, where they have been scored; `scorings` the ledger's
    count of the row's scorings (None: the row's own)."""
    task, key = row["task"], paper_key(row["variant"])
    name, paper = row_name(key), paper_task.get("rows", {}).get(key)
    paper_demos = paper_task.get("demos", [None])[0]
    test, vals = row["test"], row["validations"]
    best = min(vals, key=lambda v: v["val_rmse"])
    scored = times(test["scorings"] if scorings is None else scorings)
    lines = ["| split | episodes | success (95% interval) | paper success | goal RMSE | paper RMSE | coverage RMSE "
             "| precision RMSE |", "| --- | --- | --- | --- | --- | --- | --- | --- |"]
    for split, s in row["splits"].items():
        column = SPLITS.index(split)
        paper_rmse = paper["rmse"][column] if paper and "rmse" in paper else None
        low, high = s["success_ci95"]
        lines.append(f"| {split} | {s['episodes']} | {split_rate(s)} ({low:.2f}-{high:.2f}) | "
                     f"{cell(paper['success'][column] if paper else None, '{:.2f}')} | {cell(s.get('rmse'), '{:.3f}')} "
                     f"| {cell(paper_rmse, '{:.3f}')} | {cell(s.get('coverage_rmse'), '{:.3f}')} | "
                     f"{cell(s.get('precision_rmse'), '{:.3f}')} |")
    return "\n".join([
        f"# {name} for {task}",
        "",
        f"A {name} goal predictor (a diffusion transformer over per-point cross-displacements) for `{task}`: the "
        f"{name} row of [its table](../../docs/results/{task}.md), trained on {row['num_train']} of this project's "
        f"demonstrations (the paper trains on {paper_demos}) with the `{row['preset']}` preset "
        f"([docs/training.md](../../docs/training.md)) for a {row['minutes']:g}-minute plan on one core.",
        *usage(checkpoint),
        f"The test episodes, `unseen` and `ood` demo_{test['first_index']}-{test['first_index'] + test['episodes'] - 1}, "
        f"which no choice has touched, scored {scored} "
        f"with these weights and {test['samples']} goal samples an episode (the policy executes the first), "
        f"{row['date']}, {row['machine']}; the paper's figures from its appendix D (docs/results/paper.toml):",
        "",
        *lines,
        "",
        *bounds_line(row, bounds or {}),
        "## Training",
        "",
        network_line(config),
        f"- training demonstrations: the first {row['num_train']} of `train` (generated by the command below)",
        f"- steps: {vals[-1]['step']:,} (a {row['minutes']:g}-minute plan on one core)",
        f"- weights chosen on `{row['weights_chosen_on']}`: these are the run's {row['weights']} weights, validation "
        f"RMSE {best['val_rmse']:.3f} at step {best['step']:,} (the last validation: {vals[-1]['val_rmse']:.3f} at "
        f"step {vals[-1]['step']:,})",
        f"- weights sha256: `{row['weights_sha256']}`",
        "",
        "One command generates the demonstrations it lacks (train, `val`, the test episodes), trains, keeps the weights "
        "that validate best on `val` and scores the test episodes once:",
        "",
        "```bash",
        renamed(row["command"]),
        "```",
        "",
        *([] if renamed(row["command"]) == row["command"] else
          [f"The row records it under the command's earlier name: `{row['command']}`.", ""]),
        *limits(task, config),
    ])


class CardsPage(Page):
    """Every card the declaration lists, each written to its checkpoint's README.md."""

    required = ("card",)

    def files(self) -> dict[Path, bytes]:
        repository = self.root.parent.parent
        out = {}
        for c in self.spec.get("card", []):
            folder = repository / c["checkpoint"]
            config = kept.config(folder / "config.json")
            if c.get("row"):
                row = kept.read(self.root / c["row"], ("table-row",))
                if config.get("weights_sha256") != row["weights_sha256"]:
                    raise UsageError(f"{c['checkpoint']}/config.json: weights sha256 {config.get('weights_sha256')}; "
                                     f"expected {row['weights_sha256']}, the weights of the row {c['row']}")
                bounds = {key: kept.read(path, ("table-row",)) for key in FIXED_GOALS
                          if (path := (self.root / c["row"]).parent / f"{key}.json").is_file()}
                lines = ledger.of_row(ledger.read(self.root / "table" / "ledger.jsonl"), row["task"], row["num_train"],
                                      row["variant"])
                out[folder / "README.md"] = row_card(c["checkpoint"], config, row, self.paper_all.get(row["task"], {}),
                                                     bounds, len(lines)).encode()
                continue
            summary = kept.load(self.root / c["eval"], ("eval",))
            records = kept.read(self.root / c["log"], ("train-log",))["records"] if c.get("log") else []
            official = kept.load(self.root / c["official"], ("official-val",)) if c.get("official") else None
            out[folder / "README.md"] = card(c["checkpoint"], config, records, summary, c["data"], c["train"],
                                             self.paper_all, official).encode()
        return out
