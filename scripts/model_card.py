"""Write a shipped checkpoint's model card (its README.md) from the files that describe it, no number typed by hand.

    python scripts/model_card.py checkpoints/tax3d-cd-unimodal --log docs/results/training/RUN-log.json \
        --eval docs/results/evals/NAME.json --data-command "..." --train-command "..."

--log is a run's log.jsonl, or a kept JSON `{"records": [...]}` of its plan, validation and last lines
(scripts/keep_log.py; left out for a run whose log was not kept: the card then says so); --eval a kept `tax3d eval`
summary. The card says what the checkpoint is for, how it was made and how well it does, beside the paper's success and
RMSE for the same task and variant (docs/results/paper.toml).

    python scripts/model_card.py checkpoints/tax3d-cd-official-simple --official docs/results/official_val.json ...

--official marks a checkpoint trained on the authors' demonstrations and adds the RMSE on their `val` split that
scripts/official_report.py measured.
"""

from __future__ import annotations

import argparse
import json
import sys
import tomllib
from pathlib import Path

from tax3d.atomic import write_text
from tax3d.checkpoint import read_log

PAPER = Path(__file__).resolve().parents[1] / "docs" / "results" / "paper.toml"
SPLITS = ("train", "unseen", "ood")


def paper_row(task: str, variant: str) -> dict | None:
    """The paper's row for this task and variant (its appendix D table), or None."""
    return tomllib.loads(PAPER.read_text()).get(task, {}).get("rows", {}).get(variant.upper())


def _cell(value, fmt: str) -> str:
    return "-" if value is None else fmt.format(value)


def success_table(splits: dict, paper: dict | None) -> list[str]:
    lines = ["| split | episodes | success | paper success | goal RMSE | paper RMSE | coverage RMSE |",
             "| --- | --- | --- | --- | --- | --- | --- |"]
    for name, split in splits.items():
        column = SPLITS.index(name) if name in SPLITS else None
        paper_success = paper["success"][column] if paper and column is not None else None
        paper_rmse = paper["rmse"][column] if paper and column is not None and "rmse" in paper else None
        lines.append(f"| {name} | {split['episodes']} | {split['success_rate']:.2f} | {_cell(paper_success, '{:.2f}')} "
                     f"| {_cell(split.get('rmse'), '{:.3f}')} | {_cell(paper_rmse, '{:.3f}')} "
                     f"| {_cell(split.get('coverage_rmse'), '{:.3f}')} |")
    return lines


def run_lines(config: dict, records: list[dict], plan: dict | None) -> list[str]:
    """Steps and wall time from the run's log; from its configuration alone when the log was not kept."""
    threads = config["train"].get("threads", 0)
    where = ("a GPU" if config["train"].get("device") == "cuda" else "one core" if threads == 1
             else f"{threads} threads" if threads else "torch's default threads")
    if not records:
        limit = config["train"].get("time_limit", 0)
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
              f"Command: `{report['command']}`"]
    return lines


def card(checkpoint: Path, config: dict, records: list[dict], summary: dict, data_command: str, train_command: str,
         official: dict | None = None) -> str:
    plan = next((r["plan"] for r in records if "plan" in r), None)
    vals = [r for r in records if "val_rmse" in r]
    best = min(vals, key=lambda r: r["val_rmse"]) if vals else None
    task, variant = config["data"]["task"], config["model"]["variant"]
    paper = paper_row(task, variant)
    source = ("the authors' demonstrations" if official else "this project's own demonstrations")
    lines = [
        f"# TAX3D-{variant.upper()} for {task}",
        "",
        f"A TAX3D-{variant.upper()} goal predictor (a diffusion transformer over per-point cross-displacements) for "
        f"`{task}`, trained on {source} with the `cpu` recipe of "
        f"[docs/training.md](../../docs/training.md).",
        "",
        "```python",
        "from tax3d import Tax3D",
        f'model = Tax3D.from_pretrained("{checkpoint.as_posix()}")',
        "goals = model.predict(action_points, anchor_points, num_samples=5)  # (5, N, 3), world frame",
        "```",
        "",
        "## Results",
        "",
        f"`tax3d eval` on {summary['task']}, {summary['date']}, {summary['machine']}; the paper's figures from "
        f"its appendix D (docs/results/paper.toml):",
        "",
        *success_table(summary["splits"], paper),
        "",
        f"Command: `{summary['command']}`",
        *(official_lines(official, paper) if official else []),
        "",
        "## Training",
        "",
        f"- network: hidden {config['model']['hidden_size']}, depth {config['model']['depth']}; loss "
        f"`{config['diffusion'].get('loss', 'epsilon')}`, prediction `{config['diffusion']['prediction']}`, "
        f"sampler {config['diffusion']['sample_steps']}-step {config['diffusion']['sampler'].upper()}"
        + (f"; the grasped vertices weigh {config['data']['grip_weight']:g} in the loss"
           if config["data"].get("grip_weight", 1.0) != 1.0 else ""),
        "- training demonstrations: " + ", ".join(f"`{folder}`" for folder in config["data"]["train"])
        + " (made by the first command below)",
        *run_lines(config, records, plan),
    ]
    if best is not None and Path(summary.get("checkpoint", "")).name == "last" and vals[-1] is not best:
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
    return "\n".join(lines)


class Refused(Exception):
    """Bad input: one line naming the file, what was wrong and what was expected."""


def load(path: Path, key: str, expected: str) -> dict:
    """path's JSON object, which must hold `key` (a log.jsonl: {"records": its lines}), or Refused."""
    try:
        data = {"records": read_log(path)} if path.suffix == ".jsonl" else json.loads(path.read_text())
        if key not in data:
            raise KeyError(key)
        return data
    except (OSError, ValueError, KeyError, TypeError) as err:
        raise Refused(f"{path}: not readable ({type(err).__name__}); expected {expected}") from None


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("checkpoint", type=Path)
    parser.add_argument("--log", type=Path, help="a run's log.jsonl, or its kept JSON (left out: not kept)")
    parser.add_argument("--eval", type=Path, required=True)
    parser.add_argument("--data-command", required=True)
    parser.add_argument("--train-command", required=True)
    parser.add_argument("--official", type=Path, help="scripts/official_report.py's JSON: trained on the authors' data")
    args = parser.parse_args()
    try:
        config = load(args.checkpoint / "config.json", "data",
                      "a checkpoint folder whose config.json has a 'data' section")
        summary = load(args.eval, "summary", "a kept `tax3d eval` summary")["summary"]
        records = [] if args.log is None else load(
            args.log, "records", "a run's log.jsonl or a kept JSON with 'records'")["records"]
        official = None if args.official is None else load(
            args.official, "samplers", "scripts/official_report.py's JSON")
    except Refused as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    write_text(args.checkpoint / "README.md", card(args.checkpoint, config, records, summary, args.data_command,
                                                   args.train_command, official))
    print(args.checkpoint / "README.md")
    return 0


if __name__ == "__main__":
    sys.exit(main())
