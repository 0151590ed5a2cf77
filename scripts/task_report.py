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
    paper_episodes: str = "16 / 40 / 40"
    # variant: ((coverage RMSE train, unseen, ood), (precision RMSE train, unseen, ood)); multimodal only
    paper_sets: dict | None = None
    script: str = "python scripts/task_report.py"


# Appendix D, every table: RMSE (train, unseen, ood), success (train, unseen, ood).
SIMPLE = {
    "CD": ((0.270, 0.255, 0.498), (1.00, 1.00, 0.98)), "CP": ((0.298, 0.277, 0.518), (1.00, 1.00, 0.98)),
    "SD": ((0.054, 0.741, 2.898), (0.94, 0.98, 0.00)), "SP": ((0.051, 0.172, 2.969), (0.50, 0.58, 0.05)),
    "CD-W": ((0.052, 0.224, 3.680), (1.00, 1.00, 0.00)), "CP-W": ((0.044, 0.231, 3.452), (1.00, 1.00, 0.00)),
    "CD-NAC": ((1.586, 1.498, 1.741), (0.56, 0.60, 0.53)), "CP-NAC": ((3.563, 3.573, 3.534), (0.00, 0.00, 0.00)),
    "DP3": ((None, None, None), (1.00, 0.93, 0.00))}
UNIMODAL = {
    "SD": ((0.127, 0.805, 4.246), (0.27, 0.20, 0.00)), "SP": ((0.095, 0.779, 3.955), (0.45, 0.48, 0.08)),
    "CD-W": ((0.099, 0.464, 12.464), (0.95, 0.88, 0.00)), "CP-W": ((0.085, 0.511, 19.923), (0.95, 0.85, 0.00)),
    "CD-NAC": ((2.233, 2.243, 2.326), (0.16, 0.28, 0.10)), "CP-NAC": ((3.987, 3.934, 3.923), (0.02, 0.00, 0.03)),
    "CD": ((0.052, 0.405, 0.395), (0.94, 0.90, 0.85)), "CP": ((0.051, 0.390, 0.422), (0.93, 0.95, 0.80)),
    "DP3": ((None, None, None), (0.98, 0.38, 0.03))}
MULTIMODAL = {
    "SD": ((1.048, 1.361, 3.832), (0.36, 0.48, 0.05)), "SP": ((1.028, 1.407, 3.825), (0.53, 0.40, 0.05)),
    "CD-W": ((1.436, 1.535, 5.006), (0.95, 0.63, 0.03)), "CP-W": ((1.418, 1.555, 48.760), (0.97, 0.70, 0.08)),
    "CD-NAC": ((2.467, 2.560, 2.650), (0.25, 0.10, 0.10)), "CP-NAC": ((4.148, 4.237, 4.114), (0.00, 0.00, 0.00)),
    "RD": ((2.978, 2.987, 3.057), (0.53, 0.60, 0.50)), "RP": ((1.360, 1.417, 1.432), (0.47, 0.65, 0.48)),
    "CD": ((1.413, 1.532, 1.610), (0.95, 0.98, 0.73)), "CP": ((1.400, 1.568, 1.608), (0.94, 0.85, 0.70)),
    "DP3": ((None, None, None), (0.97, 0.45, 0.00))}
MULTIMODAL_SETS = {
    "SD": ((0.075, 0.740, 3.500), (1.114, 1.379, 4.214)), "SP": ((0.061, 0.773, 3.462), (1.093, 1.432, 4.062)),
    "CD-W": ((0.054, 0.426, 4.269), (0.132, 0.477, 4.351)), "CP-W": ((0.047, 0.446, 33.868), (0.099, 0.504, 47.372)),
    "CD-NAC": ((1.484, 1.741, 1.812), (1.785, 2.011, 2.167)), "CP-NAC": ((3.593, 3.720, 3.603), (3.770, 3.914, 3.786)),
    "RD": ((2.978, 2.987, 3.057), (1.296, 1.087, 1.114)), "RP": ((1.360, 1.417, 1.432), (1.305, 1.192, 1.154)),
    "CD": ((0.040, 0.457, 0.543), (0.084, 0.403, 0.558)), "CP": ((0.038, 0.453, 0.540), (0.087, 0.495, 0.631))}
CLOTH_POLICY = ("the goal-conditioned policy (predicted positions of vertices 0 and 24 as open-loop gripper targets, "
                "300 steps, release) judged by the success check of appendix A.4.2")


TASKS = {
    "hangproccloth-simple": TaskPage(
        title="HangProcCloth-simple: TAX3D trained on our own demonstrations",
        source="appendix D.1",
        paper=SIMPLE, policy=CLOTH_POLICY,
        out=RESULTS / "hangproccloth-simple.md", script="bash scripts/simple_page.sh",
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
        out=RESULTS / "hangbag.md", script="bash scripts/hangbag_page.sh"),
    "hangproccloth-simple-baselines": TaskPage(
        title="HangProcCloth-simple: the baselines and ablations of appendix D.1",
        source="appendix D.1",
        paper=SIMPLE, policy=CLOTH_POLICY, out=RESULTS / "hangproccloth-simple-baselines.md",
        remarks="TAX3D-CD and TAX3D-CP on 40 + 40 episodes, the fidelity and closed-loop rows are in "
                "[hangproccloth-simple.md](hangproccloth-simple.md). ",
        script="bash scripts/cloth_page.sh simple"),
    "hangproccloth-unimodal": TaskPage(
        title="HangProcCloth-unimodal: random one-hole cloths",
        source="Table 1 and appendix D.2", paper=UNIMODAL, policy=CLOTH_POLICY,
        out=RESULTS / "hangproccloth-unimodal.md", paper_episodes="64 / 40 / 40", paper_sets={},
        script="bash scripts/cloth_page.sh unimodal"),
    "hangproccloth-multimodal": TaskPage(
        title="HangProcCloth-multimodal: random two-hole cloths, one demonstration per hole",
        source="Table 2 and appendix D.3", paper=MULTIMODAL, paper_sets=MULTIMODAL_SETS, policy=CLOTH_POLICY,
        out=RESULTS / "hangproccloth-multimodal.md", paper_episodes="64 / 40 / 40",
        script="bash scripts/cloth_page.sh multimodal"),
}


def load_summary(path: Path) -> dict:
    """`tax3d eval`'s summary: from EVAL_DIR/results.json, or from a JSON file that keeps it (`{"summary": ...}`)."""
    file = path / "results.json" if path.is_dir() else path
    return json.loads(file.read_text())["summary"]


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


def curve_section(pairs: list[str]) -> list[str]:
    """A table of validation RMSE (best of the samples) per step, one column per NAME=JSON curve."""
    names, curves = [], []
    for pair in pairs:
        name, path = pair.split("=", 1)
        names.append(name)
        curves.append(json.loads(Path(path).read_text()))
    by_step = [{p["step"]: p["val_rmse"] for p in c["points"]} for c in curves]
    steps = sorted(set().union(*by_step))
    first = curves[0]
    lines = ["## Validation RMSE over training", "",
             f"The best of {first['val_samples']} goal samples per demo, averaged over the first {first['val_demos']} "
             f"demos of `{', '.join(first['val'])}`, as logged by `tax3d train` (kept by `scripts/val_curve.py`):", "",
             "| step | " + " | ".join(names) + " |", "| --- |" + " --- |" * len(names)]
    lines += [f"| {s:,} | " + " | ".join(cell(b.get(s), "{:.3f}") for b in by_step) + " |" for s in steps]
    return lines + [""]


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--eval", nargs="+", required=True, help="NAME=EVAL_DIR pairs")
    parser.add_argument("--train-command", action="append", default=[], help="the training commands, verbatim")
    parser.add_argument("--task", default="hangproccloth-simple", help=", ".join(TASKS))
    parser.add_argument("--note", action="append", default=[], help="a paragraph to add under the table")
    parser.add_argument("--baseline", nargs="*", default=[], help="NAME=JSON pairs from scripts/oracle_policy.py: "
                        "fixed-goal rows (the demo's own goal, the mean goal)")
    parser.add_argument("--goal-spread", type=Path, default=None, help="JSON of scripts/goal_spread.py")
    parser.add_argument("--mode-spread", type=Path, default=None, help="JSON of scripts/mode_spread.py (multimodal)")
    parser.add_argument("--curve", nargs="*", default=[], help="NAME=JSON pairs from scripts/val_curve.py: validation "
                        "RMSE over the steps of training runs")
    parser.add_argument("--plot", action="store_true", help="also draw the success rates as bars, PAGE.png")
    parser.add_argument("--out", type=Path, default=None, help="default: the task's page in docs/results/")
    args = parser.parse_args(argv)
    if args.task not in TASKS:
        parser.exit(2, f"error: --task {args.task!r}: expected one of {', '.join(TASKS)}\n")
    page = TASKS[args.task]
    out = args.out or page.out
    script = page.script
    lines = [f"# {page.title}", "", f"Generated by `{script}` from the `results.json` of each "
             f"evaluation; the paper's figures are from its {page.source}.", ""]
    rows, notes, timings, offsets, bars, set_rows = [], [], [], [], [], []

    def set_row(label_text: str, table: dict) -> str:
        values = [table.get(k, {}).get(m) for m in ("coverage_rmse", "precision_rmse") for k in SPLITS]
        return f"| {label_text} | " + " | ".join(cell(v, "{:.3f}") for v in values) + " |"
    for pair in args.eval:
        name, folder = pair.split("=", 1)
        s = load_summary(Path(folder))
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
                        + " | ".join(f"{v:.2f}" for v in p) + f" | {page.paper_episodes} |")
        set_rows.append(set_row(f"{label(name)} (ours)", table))
        if page.paper_sets is not None and name in page.paper_sets:
            cov, prec = page.paper_sets[name]
            set_rows.append(f"| {label(name)} (paper) | " + " | ".join(f"{v:.3f}" for v in (*cov, *prec)) + " |")
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
        if not exact:
            set_rows.append(set_row(name, table))
        notes.append(f"- {name}: `{b['command']}` (gripper-target offset {offset_text(b['offset'])}), {b['machine']}, "
                     f"{b['date']}.")
    known = [o for o in offsets if o is not None]
    policy = page.policy.format(offset=offset_text(known[0]) if known else "the task's offset")
    lines += ["| | RMSE train | RMSE unseen | RMSE ood | success train | success unseen | success ood | episodes |",
              "| --- | --- | --- | --- | --- | --- | --- | --- |", *rows, "",
              *([f"![success per split]({plot_success(bars, out.with_suffix('.png'))})", ""] if args.plot else []),
              "RMSE: world frame, mean over the episodes of each split of the predicted goal against the demonstration's "
              + ("goal (with several goal samples per episode, their mean)" if page.paper_sets is not None else "goal")
              + f"; success: {policy}.", "",
              page.remarks + "Each checkpoint is the lowest validation RMSE on 10 `unseen` demos, a mild selection bias "
              "on that split.", ""]
    if page.paper_sets is not None:
        lines += ["## Coverage and precision RMSE", "",
                  "| | coverage train | coverage unseen | coverage ood | precision train | precision unseen | "
                  "precision ood |", "| --- | --- | --- | --- | --- | --- | --- |", *set_rows, "",
                  "Coverage RMSE: for each demonstrated goal of a cloth (one per hole), the lowest RMSE among the goals "
                  "sampled for that cloth; precision RMSE: for each sampled goal, the lowest RMSE to the cloth's "
                  "demonstrated goals; both averaged over the cloths of the split (appendix C).", ""]
    lines += [*[n + "\n" for n in args.note], "Evaluation commands:", *notes, ""]
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
    if args.mode_spread is not None:
        m = json.loads(args.mode_spread.read_text())
        names = list(m["splits"])
        lines += ["## How far apart the two modes are", "", f"`{m['command']}`, {m['date']} (no simulation: the demos' "
                  "goals, over the cloths with a demonstration for each hole):", "", "| | " + " | ".join(names) + " |",
                  "| --- |" + " --- |" * len(names),
                  "| RMSE between a cloth's two goals | " + " | ".join(
                      cell(m["splits"][k]["goal_separation_rmse"], "{:.3f}") for k in names) + " |",
                  "| RMSE of their midpoint to either goal (its coverage and precision RMSE) | " + " | ".join(
                      cell(m["splits"][k]["midpoint_rmse"], "{:.3f}") for k in names) + " |", ""]
    if args.curve:
        lines += curve_section(args.curve)
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
