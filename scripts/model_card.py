"""Write a shipped checkpoint's model card (its README.md) from the files that describe it, no number typed by hand.

    python scripts/model_card.py checkpoints/tax3d-cd-unimodal --log docs/results/training/RUN-log.json \
        --eval docs/results/evals/NAME.json --data-command "..." --train-command "..." [--paper 0.94/0.90/0.85]

--log is a training log kept as JSON (`{"records": [...]}` from log.jsonl, see --keep-log), --eval a kept
`tax3d eval` summary. The card says what the checkpoint is for, how it was made and how well it does, beside the
paper's success where --paper gives it (train/unseen/ood).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from tax3d.atomic import write_text
from tax3d.checkpoint import read_log


def success_table(splits: dict, paper: list[str] | None) -> list[str]:
    lines = ["| split | episodes | success | goal RMSE | coverage RMSE |" + (" paper success |" if paper else ""),
             "| --- | --- | --- | --- | --- |" + (" --- |" if paper else "")]
    for name, split in splits.items():
        extra = ""
        if paper:
            extra = f" {dict(zip(('train', 'unseen', 'ood'), paper)).get(name, '-')} |"
        rmse = "-" if split.get("rmse") is None else f"{split['rmse']:.3f}"
        coverage = "-" if split.get("coverage_rmse") is None else f"{split['coverage_rmse']:.3f}"
        lines.append(f"| {name} | {split['episodes']} | {split['success_rate']:.2f} | {rmse} | {coverage} |{extra}")
    return lines


def card(checkpoint: Path, records: list[dict], summary: dict, data_command: str, train_command: str,
         paper: list[str] | None) -> str:
    config = json.loads((checkpoint / "config.json").read_text())
    plan = next((r["plan"] for r in records if "plan" in r), None)
    vals = [r for r in records if "val_rmse" in r]
    best = min(vals, key=lambda r: r["val_rmse"]) if vals else None
    task, variant = config["data"]["task"], config["model"]["variant"]
    last = records[-1]
    lines = [
        f"# TAX3D-{variant.upper()} for {task}",
        "",
        f"A TAX3D-{variant.upper()} goal predictor (a diffusion transformer over per-point cross-displacements) for "
        f"`{task}`, trained on this project's own demonstrations with the `cpu` recipe of "
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
        f"`tax3d eval` on {summary['task']}, {summary['date']}, {summary['machine']}:",
        "",
        *success_table(summary["splits"], paper),
        "",
        f"Command: `{summary['command']}`",
        "",
        "## Training",
        "",
        f"- network: hidden {config['model']['hidden_size']}, depth {config['model']['depth']}; loss "
        f"`{config['diffusion'].get('loss', 'epsilon')}`, prediction `{config['diffusion']['prediction']}`, "
        f"sampler {config['diffusion']['sample_steps']}-step {config['diffusion']['sampler'].upper()}",
        f"- steps: {last['step']}" + (f" (planned for {plan['minutes']:g} minutes)" if plan else ""),
        f"- wall time: {last['seconds'] / 60:.0f} minutes on one core",
    ]
    if best is not None:
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
        "- Trained without rotation augmentation: anchor poses far outside the training range are out of its "
        "reach, and the success above is measured in simulation only.",
        "- A CPU-budget model: see the table against the paper's before relying on it.",
        "",
    ]
    return "\n".join(lines)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("checkpoint", type=Path)
    parser.add_argument("--log", type=Path, required=True, help="a run's log.jsonl, or its kept JSON")
    parser.add_argument("--eval", type=Path, required=True)
    parser.add_argument("--data-command", required=True)
    parser.add_argument("--train-command", required=True)
    parser.add_argument("--paper", help="the paper's success, train/unseen/ood, e.g. 0.94/0.90/0.85")
    args = parser.parse_args()
    if args.log.suffix == ".jsonl":
        records = read_log(args.log)
    else:
        records = json.loads(args.log.read_text())["records"]
    summary = json.loads(args.eval.read_text())["summary"]
    paper = args.paper.split("/") if args.paper else None
    write_text(args.checkpoint / "README.md", card(args.checkpoint, records, summary, args.data_command,
                                                   args.train_command, paper))
    print(args.checkpoint / "README.md")
    return 0


if __name__ == "__main__":
    sys.exit(main())
