"""docs/results/training-speed.md (`kind = "speed"`): where a CPU training step goes, the speed levers, and each
lever's runs side by side at equal wall time."""

from __future__ import annotations

from pathlib import Path

from tax3d.errors import UsageError
from lab.results.pages import plots
from lab.results.pages.measurement import MeasurementPage
from lab.results.pages.page import fold, provenance


class SpeedPage(MeasurementPage):
    """docs/results/training-speed.md: where a CPU training step goes, the speed levers, and each lever's runs side
    by side at equal wall time (sources: `table = "profile"`, a benchmarks/train_step.py JSON, and `table = "pair"`,
    lab.studies.time_to_quality JSON). `plot` names the pairs whose validation curves the page's plot draws."""

    def markdown(self) -> str:
        profile = self.sources("profile")[0]
        peaks = profile["matmul_peak_flops"]
        lines = [f"# {self.spec['title']}", "", self.verdict(), ""]
        if self.spec.get("plot"):
            lines += [f"![validation RMSE against training minutes]({self.name}.png)", "",
                      "Validation RMSE against training minutes, one core a run: "
                      + "; ".join(f"{p['id']}, {p['label']} (trained on `{' '.join(p['train'])}`)" for p in self._plotted())
                      + ".", ""]
        lines += ["## Where a step goes", "",
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
            plans = sorted({r["plan"]["minutes"] for r in runs.values() if r.get("plan")} or {pair["minutes"]})
            threads = pair.get("threads_per_run", 1)
            cores = "one core" if threads == 1 else f"{threads} cores and {threads} torch threads"
            if len(runs) == 1:
                how = f"a {plans[0]:g}-minute plan on {cores}"
            elif len(plans) == 1:
                how = f"{plans[0]:g}-minute plans, {cores} each, started together"
            else:
                how = f"plans of {' and '.join(f'{m:g}' for m in plans)} minutes, {cores} each, started together"
            sampled = [n for n, r in runs.items() if r.get("config", {}).get("train", {}).get("val_points") == "sampled"]
            where = (f"; {', '.join(sampled)}: the network's input a farthest-point sample of its training size, the "
                     f"RMSE on whole clouds" if sampled else "")
            lines += [f"**{pair['label']}** ({how}; "
                      f"validation RMSE on the first {pair['val_demos']} demos of `{' '.join(pair['val'])}`, best of "
                      f"{pair['val_samples']} samples{where}):", "",
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
            lines += ["", *fold("How each policy row was measured",
                                [f"- {p['label']}: {provenance(p)} ([{p['file']}]({p['file']}))." for p in policy])]
        lines += self.notes("pairs")
        lines += self.details()
        return "\n".join(lines).rstrip() + "\n"

    def _plotted(self) -> list[dict]:
        pairs = {s["id"]: s for s in self.spec.get("source", []) if s.get("table") == "pair"}
        unknown = [i for i in self.spec["plot"] if i not in pairs]
        if unknown:
            raise UsageError(f"{self.name}.toml: plot names {', '.join(unknown)}; expected ids of its "
                             f"`table = \"pair\"` sources ({', '.join(pairs)})")
        return [self.data[i] | {"id": i, "label": pairs[i]["label"]} for i in self.spec["plot"]]

    def plot(self) -> bytes:
        pairs = self._plotted()
        runs = [(f"{p['id']}: {name}", [c["minutes"] for c in r["curve"]], [c["val_rmse"] for c in r["curve"]])
                for p in pairs for name, r in p["runs"].items()]
        demos = sorted({p["val_demos"] for p in pairs})
        return plots.validation_curves(runs, None, f"validation RMSE ({'/'.join(map(str, demos))} val demos)")

    def files(self) -> dict[Path, bytes]:
        out = super().files()
        if self.spec.get("plot"):
            out[self.root / f"{self.name}.png"] = self.plot()
        return out
