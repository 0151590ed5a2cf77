"""The time-to-quality study of docs/training.md: its table and plot, built from the kept benchmark JSON files.

    python scripts/training_study.py docs/results/training/*.json [--floor FILE] [--page docs/training.md]

Each JSON file is one `benchmarks/time_to_quality.py` comparison. The table gets one row per run: its options, the
validation RMSE at the validations nearest 15, 30 and 60 minutes (and at its end), and its steps per minute; the
plot draws every run's validation RMSE against minutes, with the mean-goal floor of `--floor` (a `tax3d predict
--summary` JSON with `rmse_mean_goal_baseline`). The text between the page's `<!-- study -->` and
`<!-- /study -->` lines is replaced; nothing else of the page changes.
"""

from __future__ import annotations

import argparse
import json
import sys
import tomllib
from pathlib import Path

from tax3d.atomic import atomic_write, write_text

MARKS = (15, 30, 60)
PAPER = Path(__file__).resolve().parents[1] / "docs" / "results" / "paper.toml"  # appendix D of the paper
PAPER_UNSEEN_RMSE = tomllib.loads(PAPER.read_text())["hangproccloth-unimodal"]["rows"]["CD"]["rmse"][1]


def at_minute(curve: list[dict], mark: float) -> dict | None:
    """The last validation at or before `mark` minutes, allowing 10% for a run slowed by other work."""
    before = [point for point in curve if point["minutes"] <= 1.1 * mark]
    return before[-1] if before else None


def cell(point: dict | None) -> str:
    return "-" if point is None else f"{point['val_rmse']:.3f} ({point['minutes']:.0f} min)"


def first_rate(result: dict) -> str:
    """Steps per minute over the run's first steps (its plan's measurement, before other work shared the core)."""
    plan = result.get("plan")
    return f"{60 / plan['step_seconds']:.0f}" if plan else "-"


def rows(studies: list[tuple[str, dict]]) -> list[str]:
    lines = ["| study | run | options added to the `cpu` preset of the time | " +
             " | ".join(f"RMSE @ {m} min" for m in MARKS) + " | at the end | steps / min (whole run) | steps / min (first steps) |",
             "| --- | --- | --- | " + " | ".join("---" for _ in MARKS) + " | --- | --- | --- |"]
    for name, study in studies:
        for run, result in study["runs"].items():
            curve = result["curve"]
            marks = " | ".join(cell(at_minute(curve, m)) for m in MARKS)
            options = f"`{result['options']}`" if result["options"] else "(none)"
            lines.append(f"| {name} | {run} | {options} | {marks} | {cell(curve[-1] if curve else None)} | "
                         f"{result['steps_per_minute']:.0f} | {first_rate(result)} |")
    return lines


def plot(studies: list[tuple[str, dict]], floor: float | None, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.4, 3.6), dpi=110)
    for name, study in studies:
        for run, result in study["runs"].items():
            curve = result["curve"]
            ax.plot([p["minutes"] for p in curve], [p["val_rmse"] for p in curve], marker="o", label=f"{name}: {run}")
    if floor is not None:
        ax.axhline(floor, color="grey", linestyle="--", label="mean-goal floor")
    ax.set_xlabel("training minutes (one core each)")
    ax.set_ylabel("validation RMSE (20 unseen demos)")
    ax.set_ylim(bottom=0)
    ax.legend(fontsize=7)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    atomic_write(path, lambda tmp: fig.savefig(tmp, format="png"))
    plt.close(fig)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("studies", nargs="+", type=Path)
    parser.add_argument("--floor", type=Path)
    parser.add_argument("--page", type=Path, default=Path("docs/training.md"))
    parser.add_argument("--plot", type=Path, default=Path("docs/results/training/time_to_quality.png"))
    args = parser.parse_args()
    studies = [(path.stem, json.loads(path.read_text())) for path in args.studies]
    floor = json.loads(args.floor.read_text())["rmse_mean_goal_baseline"] if args.floor else None
    page = args.page.read_text()
    if "<!-- study -->" not in page or "<!-- /study -->" not in page:
        print(f"{args.page}: no <!-- study --> ... <!-- /study --> lines to fill", file=sys.stderr)
        return 2
    first = studies[0][1]
    ends = [(result["curve"][-1], f"{name}: {run}") for name, study in studies for run, result in study["runs"].items()
            if result["curve"]]
    best, label = min(ends, key=lambda e: e[0]["val_rmse"])
    lines = [f"**Best at the end of its run: {label}, validation RMSE {best['val_rmse']:.3f} after "
             f"{best['minutes']:.0f} minutes** (mean-goal floor {floor:.3f}; the paper's TAX3D-CD, 500k GPU steps: "
             f"{PAPER_UNSEEN_RMSE} on its unseen split)." if floor is not None else "", ""]
    lines += rows(studies)
    lines += ["", f"![validation RMSE against minutes](results/training/{args.plot.name})", "",
              f"Machine: {first['machine']}, {first['date']}; each run pinned to one core (its data worker too), "
              f"validated {len(next(iter(first['runs'].values()))['curve'])} times on the first "
              f"{first['val_demos']} demos of `{' '.join(first['val'])}` with min-of-{first['val_samples']} RMSE "
              f"and the checkpoint's own sampler."]
    if floor is not None:
        lines[-1] += f" Mean-goal floor on the same demos: {floor:.3f}."
    head, rest = page.split("<!-- study -->", 1)
    _, tail = rest.split("<!-- /study -->", 1)
    write_text(args.page, head + "<!-- study -->\n" + "\n".join(lines) + "\n<!-- /study -->" + tail)
    plot(studies, floor, args.plot)
    return 0


if __name__ == "__main__":
    sys.exit(main())
