"""docs/results/hangproccloth-sim.md (`kind = "sim"`): fidelity to the official demonstrations, the pseudo-expert's
success rates, simulation speed; sources `table = "fidelity"`, `"expert"` or `"speed"`."""

from __future__ import annotations

from lab.results.pages.measurement import MeasurementPage
from lab.results.pages.page import fold, provenance


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
        lines = [f"# {self.spec['title']}", "", self.verdict(), "",
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
        lines += self.details()
        return "\n".join(lines).rstrip() + "\n"
