"""Write a task's results page in docs/results/ from `tax3d eval` results, beside the paper's table.

Usage: python scripts/task_report.py --task hangbag --eval CD=runs/eval-bag-cd CP=runs/eval-bag-cp \
           --train-command "..." [--note "..."]
"""

from __future__ import annotations

import argparse
import json
from dataclasses import dataclass
from pathlib import Path

from tax3d.atomic import atomic_write, write_text

SPLITS = ("train", "unseen", "ood")
RESULTS = Path(__file__).resolve().parents[1] / "docs" / "results"


@dataclass(frozen=True)
class TaskPage:
    title: str
    source: str  # where in the paper its table is
    paper: dict  # variant: ((RMSE train, unseen, ood), (success train, unseen, ood))
    policy: str
    out: Path
    remarks: str = ""


TASKS = {
    "hangproccloth-simple": TaskPage(
        title="HangProcCloth-simple: TAX3D trained on our own demonstrations",
        source="appendix D.1",
        paper={"CD": ((0.270, 0.255, 0.498), (1.00, 1.00, 0.98)), "CP": ((0.298, 0.277, 0.518), (1.00, 1.00, 0.98))},
        policy="the goal-conditioned policy (predicted positions of vertices 0 and 24 as open-loop gripper targets, "
               "300 steps, release) judged by the success check of appendix A.4.2",
        out=RESULTS / "hangproccloth-simple.md",
        remarks="A model trained on the authors' demonstrations and executed in this scene (the row so named) is the "
                "fidelity figure of the scene. The closed-loop row predicts again from the current cloth every 100 "
                "of the 300 control steps; its RMSE is that of the first prediction. "),
    "hangbag": TaskPage(
        title="HangBag: TAX3D trained on our own demonstrations",
        source="Table 3 and appendix D (HangBag)",
        paper={"CD": ((0.183, 0.204, 0.245), (0.94, 0.83, 0.78)), "CP": ((0.173, 0.192, 0.233), (0.94, 0.93, 0.78)),
               "SD": ((0.079, 0.346, 2.041), (0.00, 0.00, 0.00)), "SP": ((0.062, 0.125, 1.886), (0.00, 0.00, 0.00)),
               "CD-W": ((0.053, 0.178, 3.337), (1.00, 0.78, 0.00)),
               "CP-W": ((0.046, 0.173, 4.204), (1.00, 0.80, 0.03)),
               "CD-NAC": ((1.254, 1.301, 1.309), (0.56, 0.38, 0.33)),
               "CP-NAC": ((1.485, 1.487, 1.486), (0.00, 0.03, 0.00)),
               "DP3": ((None, None, None), (1.00, 0.73, 0.00))},
        policy="the goal-conditioned policy (predicted positions of the two grip vertices plus {offset} as "
               "open-loop gripper targets, 300 steps, release) judged by the two centroid checks of appendix A.4.2 "
               "(threshold 1.4, before and after release)",
        out=RESULTS / "hangbag.md"),
}


def label(name: str) -> str:
    return f"TAX3D-{name}" if name in ("CD", "CP") else name


def cell(value, fmt):
    return "-" if value is None else fmt.format(value)


def offset_text(offset) -> str:
    return "(" + ", ".join(f"{v:g}" for v in offset) + ")"


def plot_success(bars: list, path: Path) -> str:
    """Grouped bars of success per split, one group per row of the table; written atomically. Returns the name."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(max(6.0, 0.55 * len(bars) + 2), 4.8))
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    width = 0.27
    for j, split in enumerate(SPLITS):
        values = [0.0 if b[1][j] is None else b[1][j] for b in bars]
        ax.bar([i + (j - 1) * width for i in range(len(bars))], values, width, label=split)
    ax.set_xticks(range(len(bars)), [b[0] for b in bars], rotation=35, ha="right", fontsize=7)
    ax.set_ylim(0, 1.22)
    ax.set_ylabel("success rate")
    ax.legend(fontsize=7, ncols=3, loc="upper center")
    fig.tight_layout()
    atomic_write(path, lambda tmp: fig.savefig(tmp, dpi=110, format="png"))
    return path.name


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--eval", nargs="+", required=True, help="NAME=EVAL_DIR pairs")
    parser.add_argument("--train-command", action="append", default=[], help="the training commands, verbatim")
    parser.add_argument("--task", default="hangproccloth-simple", help=", ".join(TASKS))
    parser.add_argument("--note", action="append", default=[], help="a paragraph to add under the table")
    parser.add_argument("--baseline", nargs="*", default=[], help="NAME=JSON pairs from scripts/oracle_policy.py: "
                        "fixed-goal rows (the demo's own goal, the mean goal)")
    parser.add_argument("--goal-spread", type=Path, default=None, help="JSON of scripts/goal_spread.py")
    parser.add_argument("--plot", action="store_true", help="also draw the success rates as bars, PAGE.png")
    parser.add_argument("--out", type=Path, default=None, help="default: the task's page in docs/results/")
    args = parser.parse_args(argv)
    if args.task not in TASKS:
        parser.exit(2, f"error: --task {args.task!r}: expected one of {', '.join(TASKS)}\n")
    page = TASKS[args.task]
    out = args.out or page.out
    script = {"hangproccloth-simple": "python scripts/simple_report.py",
              "hangbag": "bash scripts/hangbag_page.sh"}.get(args.task, "python scripts/task_report.py")
    lines = [f"# {page.title}", "", f"Generated by `{script}` from the `results.json` of each "
             f"evaluation; the paper's figures are from its {page.source}.", ""]
    rows, notes, timings, offsets, bars = [], [], [], [], []
    for pair in args.eval:
        name, folder = pair.split("=", 1)
        result = json.loads((Path(folder) / "results.json").read_text())
        s = result["summary"]
        table = s["splits"]
        rmse = [table.get(k, {}).get("rmse") for k in SPLITS]
        success = [table.get(k, {}).get("success_rate") for k in SPLITS]
        episodes = [table.get(k, {}).get("episodes") for k in SPLITS]
        offsets.append(s.get("policy_offset"))
        bars.append((f"{label(name)} (ours)", success))
        rows.append(f"| {label(name)} (ours) | " + " | ".join(cell(v, "{:.3f}") for v in rmse) + " | "
                    + " | ".join(cell(v, "{:.2f}") for v in success) + " | " + " / ".join("-" if e is None else str(e) for e in episodes) + " |")
        if name in page.paper:
            r, p = page.paper[name]
            bars.append((f"{label(name)} (paper)", list(p)))
            rows.append(f"| {label(name)} (paper) | " + " | ".join(cell(v, "{:.3f}") for v in r) + " | "
                        + " | ".join(f"{v:.2f}" for v in p) + " | 16 / 40 / 40 |")
        for k in SPLITS:
            if k in table and table[k].get("sim_seconds") is not None:
                timings.append(f"| {label(name)} | {k} | {table[k]['predict_seconds']:.2f} | "
                               f"{table[k]['sim_seconds']:.2f} |")
        notes.append(f"- {label(name)}: `{s['command']}` (checkpoint `{s['checkpoint']}`), {s['machine']}, {s['date']}.")
    for pair in args.baseline:
        name, path = pair.split("=", 1)
        b = json.loads(Path(path).read_text())
        table = b["splits"]
        exact = b.get("goal") == "demo"  # the demo's own goal: zero RMSE by construction
        rows.append(f"| {name} | " + " | ".join("-" if exact else cell(table.get(k, {}).get("rmse"), "{:.3f}")
                                                for k in SPLITS) + " | "
                    + " | ".join(cell(table.get(k, {}).get("success_rate"), "{:.2f}") for k in SPLITS) + " | "
                    + " / ".join(str(table[k]["episodes"]) if k in table else "-" for k in SPLITS) + " |")
        bars.append((name, [table.get(k, {}).get("success_rate") for k in SPLITS]))
        notes.append(f"- {name}: `{b['command']}` (gripper-target offset {offset_text(b['offset'])}), {b['machine']}, "
                     f"{b['date']}.")
    known = [o for o in offsets if o is not None]
    policy = page.policy.format(offset=offset_text(known[0]) if known else "the task's offset")
    lines += ["| | RMSE train | RMSE unseen | RMSE ood | success train | success unseen | success ood | episodes |",
              "| --- | --- | --- | --- | --- | --- | --- | --- |", *rows, "",
              *([f"![success per split]({plot_success(bars, out.with_suffix('.png'))})", ""] if args.plot else []),
              "RMSE: world frame, mean over the episodes of each split of the predicted goal against the demonstration's "
              f"goal; success: {policy}.", "",
              page.remarks + "Each checkpoint is the lowest validation RMSE on 10 `unseen` demos, a mild selection bias "
              "on that split.", "", *[n + "\n" for n in args.note], "Evaluation commands:", *notes, ""]
    if args.train_command:
        lines += ["Training commands:", *[f"- {c.split(' :: ')[0]}: `{c.split(' :: ')[1]}`" if " :: " in c
                                          else f"- `{c}`" for c in args.train_command], ""]
    if args.goal_spread is not None:
        g = json.loads(args.goal_spread.read_text())
        hook = g["anchor_points_off_the_pole"]
        lines += ["## How far a fixed goal gets", "", f"`{g['command']}`, {g['date']} (no simulation: the demos' goals):",
                  "", "| | " + " | ".join(g["splits"]) + " |", "| --- |" + " --- |" * len(g["splits"]),
                  "| mean goal of train in the anchor frame | " + " | ".join(
                      f"{v['mean_goal_rmse']:.3f}" for v in g["splits"].values()) + " |",
                  "| the same, turned with the anchor's true rotation (an oracle) | " + " | ".join(
                      f"{v['rotated_mean_goal_rmse']:.3f}" for v in g["splits"].values()) + " |", "",
                  "Anchor points on the hook (off the pole, near its top): " + ", ".join(
                      f"{k.replace('fps_', 'after FPS to ')}: {v}" for k, v in hook.items()) + ".", ""]
    speed = RESULTS / "eval_benchmark.json"
    if args.task == "hangproccloth-simple" and speed.exists():
        b = json.loads(speed.read_text())
        lines += ["## Evaluation speed", "", f"`{b['command']}` (checkpoint `{b['checkpoint']}`, fresh unseen poses) on "
                  f"{b['machine']}, {b['date']}, nothing else running:", "",
                  "| seconds per episode, 1 worker | of which prediction | of which simulation | "
                  "throughput 2 workers / 1 worker |", "| --- | --- | --- | --- |",
                  f"| {b['seconds_per_episode_1_worker']:.2f} | {b['predict_seconds_per_episode']:.2f} | "
                  f"{b['sim_seconds_per_episode']:.2f} | {b['throughput_ratio_2_workers']:.2f} |", ""]
    elif timings:
        lines += ["## Seconds per episode", "", "Mean over each split's episodes, per worker process, from the same "
                  "evaluations (two workers side by side, with other jobs on the machine; `benchmarks/` has the quiet-machine "
                  "figures):", "",
                  "| | split | prediction | simulation |", "| --- | --- | --- | --- |", *timings, ""]
    write_text(out, "\n".join(lines))
    print(out)


if __name__ == "__main__":
    main()
