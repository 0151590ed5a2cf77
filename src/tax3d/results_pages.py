"""The measurement pages of `tax3d results`: the simulation page, the official-data page and the training study.

A declaration with `kind = "sim"`, `"official"` or `"training"` holds `title`, `verdict`, `source` (the kept JSON,
each with `id`, `label`, `summary` and, on the simulation page, `table`: fidelity, expert or speed) and `note`
(title, text, `section`, optional fold); the tables are built here from the sources, the notes are filled like a
task page's. The training study's declaration names the page it fills between `<!-- study -->` and
`<!-- /study -->` (`page`), its plot (`plot`), the study files (`studies`, a glob) and the minutes of its table
(`marks`).
"""

from __future__ import annotations

import io
import itertools
import json
import os
import re

from tax3d.commands import shown
from tax3d.errors import UsageError
from tax3d.results import Page, fold


def provenance(d: dict) -> str:
    return f"{shown(d['command'])} on {d['machine']}, {d['date']}"


class MeasurementPage(Page):
    def notes(self, section: str) -> list[str]:
        return [line for note in self.spec.get("note", []) if note.get("section") == section
                for line in self.section(note)]

    def sources(self, table: str) -> list[dict]:
        return [self.data[s["id"]] | {"file": s["summary"], "label": s["label"]} for s in self.spec.get("source", [])
                if s.get("table") == table]

    def files(self) -> dict:
        return {self.root / f"{self.name}.md": self.markdown().encode()}


class SimPage(MeasurementPage):
    """docs/results/hangproccloth-sim.md: fidelity to the official demos, the pseudo-expert, simulation speed."""

    def markdown(self) -> str:
        fid = self.sources("fidelity")[0]
        splits = [k for k in ("train", "val") if k in fid]
        under = next(k for k in fid[splits[0]] if k.startswith("goal_rmse_under_"))
        rows = [("official demos compared", lambda r: f"{r['demos']}"),
                ("max abs diff, initial cloth vs `action_pc`", lambda r: f"{r['init_max_abs_diff']:.1e}"),
                ("anchor cloud vs `anchor_pc`, mean symmetric NN (mean / max)",
                 lambda r: f"{r['anchor_nn_mean']:.4f} / {r['anchor_nn_max']:.4f}"),
                ("pseudo-expert episodes on the official scenes", lambda r: f"{r['episodes']}"),
                ("pseudo-expert success", lambda r: f"{r['expert_success']:.2f}"),
                ("goal RMSE against the official goal (mean / median / max)",
                 lambda r: f"{r['goal_rmse_mean']:.3f} / {r['goal_rmse_median']:.3f} / {r['goal_rmse_max']:.3f}"),
                (f"demos with goal RMSE under {under.rsplit('_', 1)[1]}", lambda r: f"{r[under]}")]
        lines = [f"# {self.spec['title']}", "", self.fill(self.spec["verdict"]), "",
                 "| | " + " | ".join(f"`{k}`" for k in splits) + " |", "| --- |" + " --- |" * len(splits)]
        lines += [f"| {label} | " + " | ".join(cell(fid[k]) for k in splits) + " |" for label, cell in rows]
        lines += ["", f"Measured by {provenance(fid)} ([{fid['file']}]({fid['file']})).", "",
                  *self.notes("fidelity"), "## Pseudo-expert success rate", "",
                  "| task | split | episodes | success rate | exploded |", "| --- | --- | --- | --- | --- |"]
        experts = self.sources("expert")
        lines += [f"| {r['task']} | `{r['split']}` | {r['episodes']} | {r['success_rate']:.2f} | {r['exploded']} |"
                  for e in experts for r in e["rates"]]
        lines += ["", *[f"- [{e['file']}]({e['file']}): {provenance(e)}." for e in experts], "",
                  *self.notes("expert")]
        lines += fold("Seconds per episode inside a worker (the CPU shared with other jobs; not speed figures)",
                      ["| task | split | seconds |", "| --- | --- | --- |",
                       *[f"| {r['task']} | `{r['split']}` | {r['seconds_per_episode']:.1f} |"
                         for e in experts for r in e["rates"]]])
        speed = self.sources("speed")
        lines += ["## Speed", "", "| task | simulation steps per second | seconds per episode, one worker | "
                  "throughput of two workers over one |", "| --- | --- | --- | --- |"]
        lines += [f"| {s['task']} | {s['sim_steps_per_second']:.0f} | {s['seconds_per_episode_1_worker']:.2f} | "
                  + ("-" if s.get("throughput_ratio_2_workers") is None else f"{s['throughput_ratio_2_workers']:.2f}")
                  + " |" for s in speed]
        lines += ["", *[f"- [{s['file']}]({s['file']}): {provenance(s)}." for s in speed], "", *self.notes("speed")]
        return "\n".join(lines).rstrip() + "\n"


class OfficialPage(MeasurementPage):
    """docs/results/official-simple.md: the official-data checkpoint's RMSE on the official `val` split, its speed."""

    def __init__(self, *args):
        super().__init__(*args)
        val = self.data["val"]
        val["per_sample"] = ", ".join(f"{x:.3f}" for x in val["samplers"]["ddpm_100"]["rmse_per_sample_index"])

    def markdown(self) -> str:
        val, bench = self.data["val"], self.data["bench"]
        ddpm, ddim = val["samplers"]["ddpm_100"], val["samplers"]["ddim_10"]
        paper = self.paper["rows"]["CD"]["rmse"][1]
        lines = [f"# {self.spec['title']}", "", self.fill(self.spec["verdict"]), "",
                 f"| predictor, official `val` split ({val['demos']} demos) | RMSE (one sample) | "
                 f"min over {val['samples']} samples |", "| --- | --- | --- |",
                 f"| TAX3D-CD, this checkpoint, 100-step DDPM | **{ddpm['rmse']:.3f}** | "
                 f"{ddpm['rmse_min_of_samples']:.3f} |",
                 f"| TAX3D-CD, this checkpoint, 10-step DDIM | {ddim['rmse']:.3f} | "
                 f"{ddim['rmse_min_of_samples']:.3f} |",
                 f"| TAX3D-CD, the paper (`unseen`) | {paper:.3f} | - |",
                 f"| mean goal of `train` in the anchor frame (`tax3d.metrics.MeanGoalBaseline`) | "
                 f"{val['mean_goal_baseline_rmse']:.3f} | - |", "",
                 f"Measured by {provenance(val)}, checkpoint `{val['checkpoint']}` "
                 "([official_val.json](official_val.json)).", "", *self.notes("rmse")]
        lines += ["## Speed", "", *self.speed(bench), "",
                  f"Measured by {provenance(bench)}, nothing else running "
                  "([model_benchmark.json](model_benchmark.json) holds the full output).", "", *self.notes("speed")]
        if "large" in self.data:
            lines += ["## Depth-camera-sized clouds", "", *self.large(self.data["large"]["large_clouds"]), "",
                      f"Measured by {provenance(self.data['large'])} "
                      "([large_clouds_benchmark.json](large_clouds_benchmark.json)).", "", *self.notes("large")]
        return "\n".join(lines).rstrip() + "\n"

    @staticmethod
    def large(big: dict) -> list[str]:
        k = big["samples_per_demo"]
        lines = ["| measure | value |", "| --- | --- |",
                 f"| prediction of {big['action_points']:,} action points, network on {big['network_points']}, "
                 f"10-step DDPM | {big['latency_s']:.2f} s |",
                 f"| `val` RMSE, min of {k} samples: network on {big['network_points']} points / on every point | "
                 f"{big['rmse_sampled']:.3f} / {big['rmse_every_point']:.3f} (ratio "
                 f"**{big['rmse_ratio_sampled_vs_every_point']:.3f}**) |"]
        if "rmse_mean_sampled" in big:
            lines.append(f"| `val` RMSE, mean of {k} samples: network on {big['network_points']} points / on every "
                         f"point | {big['rmse_mean_sampled']:.3f} / {big['rmse_mean_every_point']:.3f} (ratio "
                         f"**{big['rmse_mean_ratio_sampled_vs_every_point']:.3f}**) |")
        return lines

    @staticmethod
    def speed(bench: dict) -> list[str]:
        train, cpu, pred = bench["train_step"], bench.get("train_step_cpu_preset", {}), bench.get("predict", {})
        lines = ["| measure | value |", "| --- | --- |"]
        if "ddpm_100" in pred:
            lines += [f"| prediction, {pred['action_points']} action points, 100-step DDPM | "
                      f"{pred['ddpm_100']['latency_s'] * 1000:.0f} ms |",
                      f"| prediction, 10-step respaced DDPM / DDIM | {pred['ddpm_10']['latency_s'] * 1000:.0f} / "
                      f"{pred['ddim_10']['latency_s'] * 1000:.0f} ms |",
                      f"| speed-up, 10-step DDPM over 100-step | **{pred['speedup_10_vs_100']:.1f}x** |"]
            if "speedup_10_vs_100_fastest" in pred:
                lines.append(f"| the same from the fastest call of each | {pred['speedup_10_vs_100_fastest']:.1f}x |")
            if "rmse_ratio_ddpm_10_vs_100" in pred:
                lines += [f"| `val` RMSE, min of {pred['samples_per_demo']} samples: 100-step / 10-step DDPM / "
                          f"10-step DDIM | {pred['ddpm_100']['rmse_min_of_samples']:.3f} / "
                          f"{pred['ddpm_10']['rmse_min_of_samples']:.3f} / "
                          f"{pred['ddim_10']['rmse_min_of_samples']:.3f} |",
                          f"| RMSE ratio, 10-step DDPM over 100-step | {pred['rmse_ratio_ddpm_10_vs_100']:.3f} |"]
        lines += [f"| float32 matmul peak (`torch.mm`, same run) | {bench['matmul_peak_gflops']:.0f} GFLOP/s |",
                  f"| training step, paper configuration ({train['config']}) | {train['seconds']:.2f} s |",
                  f"| its FLOPs (matmuls and attention, forward + backward) | {train['gflop']:.0f} GFLOP |",
                  f"| its FLOP rate | {train['gflops']:.0f} GFLOP/s = **{train['fraction_of_peak']:.0%} of peak** |"]
        if cpu:
            lines.append(f"| training step, `cpu` preset, one / two torch threads | "
                         f"{cpu['step_seconds_1_threads']:.3f} / {cpu['step_seconds_2_threads']:.3f} s |")
            if "batch_data_seconds" in cpu:
                lines.append(f"| one batch of `cpu`-preset samples (FPS, frames), one process | "
                             f"{cpu['batch_data_seconds']:.3f} s |")
        return lines


MARKERS = ("<!-- study -->", "<!-- /study -->")


class TrainingPage(MeasurementPage):
    """The time-to-quality study of docs/training.md: its section (verdict, table, plot, details) and its plot."""

    def __init__(self, *args):
        super().__init__(*args)
        pattern = self.spec["studies"]
        # in the order the studies were made: ttq-2 before ttq-10
        paths = sorted(self.root.glob(pattern), key=lambda p: [int(t) if t.isdigit() else t
                                                                for t in re.split(r"(\d+)", p.stem)])
        if not paths:
            raise UsageError(f"{self.file.name}: studies {pattern!r}: no file in {self.root}; expected the kept "
                             "`benchmarks/time_to_quality.py` JSON")
        self.studies = [(p.stem, json.loads(p.read_text()), p.relative_to(self.root).as_posix()) for p in paths]
        ends = [(result["curve"][-1], f"{name}: {run}") for name, study, _ in self.studies
                for run, result in study["runs"].items() if result["curve"]]
        point, label = min(ends, key=lambda e: e[0]["val_rmse"])
        self.data["best"] = {**point, "label": label}
        first = self.studies[0][1]
        counts = sorted({len(r["curve"]) for _, study, _ in self.studies for r in study["runs"].values()})
        self.data["study"] = {**first, "val_split": " ".join(first["val"]), "validations": str(counts[0]) if
                              len(counts) == 1 else f"{counts[0]} to {counts[-1]}"}

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
        commands = [f"- {name}, {run}: {shown(result['command'])}" for name, study, _ in self.studies
                    for run, result in study["runs"].items()]
        # consecutive studies made on the same machine and day share one mention of them
        measured = "; ".join(
            ", ".join(f"[{rel}]({os.path.relpath((self.root / rel).resolve(), page.parent)})" for _, _, rel in same)
            + f" on {machine}, {date}"
            for (machine, date), same in itertools.groupby(self.studies, lambda s: (s[1]["machine"], s[1]["date"])))
        lines = [self.fill(self.spec["verdict"]), "", *self.table(), "", f"![validation RMSE against minutes]({link})",
                 "", f"Measured by `benchmarks/time_to_quality.py`: {measured}; built by `tax3d results {self.name}`.",
                 "", *self.notes("study"), *fold("The command of each run", commands)]
        return "\n".join(lines).rstrip()

    def plot(self) -> bytes:
        import matplotlib
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure

        fig = Figure(figsize=(8.4, 3.8))
        FigureCanvasAgg(fig)
        ax = fig.add_subplot()
        runs = [(f"{name}: {run}", result["curve"]) for name, study, _ in self.studies
                for run, result in study["runs"].items()]
        colors = matplotlib.colormaps["tab20"].colors  # one colour a run, up to twenty runs
        for k, (label, curve) in enumerate(runs):
            ax.plot([p["minutes"] for p in curve], [p["val_rmse"] for p in curve], marker="o", markersize=4,
                    color=colors[k % len(colors)], label=label)
        if "floor" in self.data:
            ax.axhline(self.data["floor"]["rmse_mean_goal_baseline"], color="grey", linestyle="--",
                       label="mean-goal floor")
        ax.set_xlabel("training minutes (one core each)")
        ax.set_ylabel(f"validation RMSE ({self.data['study']['val_demos']} unseen demos)")
        ax.set_ylim(bottom=0)
        ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0))
        ax.grid(alpha=0.3)
        fig.tight_layout()
        out = io.BytesIO()
        fig.savefig(out, dpi=110, format="png", metadata={"Software": None})
        return out.getvalue()

    def files(self) -> dict:
        page = (self.root / self.spec["page"]).resolve()
        if not page.is_file():
            raise UsageError(f"{self.file.name}: page {page} not found; expected the page the study fills")
        text = page.read_text()
        if MARKERS[0] not in text or MARKERS[1] not in text:
            raise UsageError(f"{page}: no {MARKERS[0]} ... {MARKERS[1]} lines to fill")
        head, rest = text.split(MARKERS[0], 1)
        _, tail = rest.split(MARKERS[1], 1)
        return {page: (head + MARKERS[0] + "\n" + self.markdown() + "\n" + MARKERS[1] + tail).encode(),
                (self.root / self.spec["plot"]).resolve(): self.plot()}


KINDS = {"sim": SimPage, "official": OfficialPage, "training": TrainingPage}


class SpeedPage(MeasurementPage):
    """docs/results/training-speed.md: where a CPU training step goes, the speed levers, and each lever's runs side
    by side at equal wall time (sources: `table = "profile"`, a benchmarks/train_step.py JSON, and `table = "pair"`,
    benchmarks/time_to_quality.py JSON)."""

    def markdown(self) -> str:
        profile = self.sources("profile")[0]
        peaks = profile["matmul_peak_flops"]
        lines = [f"# {self.spec['title']}", "", self.fill(self.spec["verdict"]), "", "## Where a step goes", "",
                 f"One training step on one core ({profile['threads']} torch thread), the median of the measured "
                 f"steps; the core's matmul peak measured in the same run: {peaks['fp32'] / 1e9:.0f} GFLOP/s in "
                 f"float32, {peaks['bf16'] / 1e9:.0f} GFLOP/s in bfloat16.", "",
                 "| preset | seconds per step | data | forward | backward | optimizer | GFLOP per step | "
                 "of the fp32 peak | of the bf16 peak |", "| --- | --- | --- | --- | --- | --- | --- | --- | --- |"]
        for name, p in profile["presets"].items():
            share = p["phase_share"]
            lines.append(f"| {name} | {p['step_seconds']:.3f} | " + " | ".join(
                f"{share[k]:.0%}" for k in ("data", "forward", "backward", "optimizer"))
                + f" | {p['flops_per_step'] / 1e9:.1f} | {p['fraction_of_fp32_peak']:.0%} | "
                f"{p['fraction_of_bf16_peak']:.0%} |")
        levers = profile.get("levers", {})
        labels = {"fp32": "float32, eager (the preset)", "bf16": "bfloat16 autocast", "compile": "torch.compile",
                  "batch8": "batch 8", "batch32": "batch 32"}
        if profile.get("top_ops"):
            lines += ["", "The operators that take the most time (self CPU time, `torch.profiler`, "
                      f"`{next(iter(profile['presets']))}`):", "", "| operator | share of the step |", "| --- | --- |",
                      *[f"| `{o['op']}` | {o['share']:.0%} |" for o in profile["top_ops"]]]
        lines += ["", f"Measured by {provenance(profile)} ([{profile['file']}]({profile['file']})).", "",
                  *self.notes("profile"), "## Levers, step by step", "",
                  "| lever | seconds per step | steps per second, against the preset | samples per second, against "
                  "the preset |", "| --- | --- | --- | --- |"]
        lines += [f"| {labels.get(k, k)} | {v['step_seconds']:.3f} | {v['speedup']:.2f} | "
                  f"{v['samples_per_second_ratio']:.2f} |" for k, v in levers.items() if isinstance(v, dict)]
        if profile.get("two_threads"):
            t = profile["two_threads"]
            lines += [f"| one run on two threads | {t['step_seconds_2_threads']:.3f} | {t['speedup_2_threads']:.2f} "
                      f"(two runs of one thread each: 2 steps for every one-thread step) | - |"]
        lines += ["", *self.notes("levers"), "## Side by side at equal wall time", ""]
        for pair in self.sources("pair"):
            runs = pair["runs"]
            marks = max(len(r["curve"]) for r in runs.values())
            lines += [f"**{pair['label']}** ({pair['minutes']:g}-minute plans, one core each, started together; "
                      f"validation RMSE on the first {pair['val_demos']} demos of `{' '.join(pair['val'])}`, best of "
                      f"{pair['val_samples']} samples):", "",
                      "| run | steps | steps per minute | " + " | ".join(f"validation {i + 1}" for i in range(marks))
                      + " |", "| --- | --- | --- |" + " --- |" * marks]
            for name, r in runs.items():
                cells = [f"{p['val_rmse']:.3f} ({p['minutes']:.0f} min)" for p in r["curve"]]
                lines.append(f"| {name} | {r['steps']:,} | {r['steps_per_minute']:.0f} | "
                             + " | ".join(cells + ["-"] * (marks - len(cells))) + " |")
            lines += ["", f"Measured by `{pair['command']}` on {pair['machine']}, {pair['date']} "
                          f"([{pair['file']}]({pair['file']})).", ""]
        policy = self.sources("policy")
        if policy:
            lines += ["The policy with each run's kept weights (`best/`, chosen on the same val demos), 40 `val` episodes, "
                      "success with its 95% Wilson interval:", "", "| run | success | goal RMSE | weights |",
                      "| --- | --- | --- | --- |"]
            for p in policy:
                split = p["splits"]["val"]
                low, high = split["success_ci95"]
                lines.append(f"| {p['label']} | {split['success_rate']:.2f} ({low:.2f}-{high:.2f}) | {split['rmse']:.3f} "
                             f"| `{p['weights_sha256'][:12]}` |")
            lines += ["", *[f"- {p['label']}: {provenance(p)} ([{p['file']}]({p['file']}))." for p in policy], ""]
        lines += self.notes("pairs")
        return "\n".join(lines).rstrip() + "\n"


KINDS["speed"] = SpeedPage
