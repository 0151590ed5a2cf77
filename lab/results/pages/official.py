"""docs/results/official-simple.md (`kind = "official"`): the official-data checkpoint's RMSE on the official `val`
split and its speed; sources `val` (the RMSE), `bench` (a training step), `pred` (the checkpoint's prediction: speed,
samplers, large clouds) and `run` (its training), by id."""

from __future__ import annotations

from lab.results.pages.measurement import MeasurementPage
from lab.results.pages.page import provenance


class OfficialPage(MeasurementPage):
    """docs/results/official-simple.md: the official-data checkpoint's RMSE on the official `val` split, its speed."""

    def __init__(self, *args):
        super().__init__(*args)
        val = self.data["val"]
        val["per_sample"] = ", ".join(f"{x:.3f}" for x in val["samplers"]["ddpm_100"]["rmse_per_sample_index"])

    def markdown(self) -> str:
        val, bench, pred = self.data["val"], self.data["bench"], self.data["pred"]
        ddpm, ddim = val["samplers"]["ddpm_100"], val["samplers"]["ddim_10"]
        paper = self.paper["rows"]["CD"]["rmse"][1]
        lines = [f"# {self.spec['title']}", "", self.verdict(), "",
                 f"| predictor, official `val` split ({val['demos']} demos) | RMSE (one sample) | "
                 f"min over {val['samples']} samples |", "| --- | --- | --- |",
                 f"| TAX3D-CD, this checkpoint, 100-step DDPM | **{ddpm['rmse']:.3f}** | "
                 f"{ddpm['rmse_min_of_samples']:.3f} |",
                 f"| TAX3D-CD, this checkpoint, 10-step DDIM | {ddim['rmse']:.3f} | "
                 f"{ddim['rmse_min_of_samples']:.3f} |",
                 f"| TAX3D-CD, the paper (`unseen`) | {paper:.3f} | - |",
                 f"| mean goal of `train` in the anchor frame (`tax3d.policies.fixed.MeanGoalBaseline`) | "
                 f"{val['mean_goal_baseline_rmse']:.3f} | - |", "",
                 f"Measured by {provenance(val)}, checkpoint `{val['checkpoint']}` "
                 "([official_val.json](official_val.json)).", "", *self.notes("rmse")]
        lines += ["## Speed", "", *self.speed(pred["predict"], bench), "",
                  f"Prediction measured by {provenance(pred)} ([predict_benchmark.json](predict_benchmark.json)); "
                  f"the training step by {provenance(bench)}, nothing else running "
                  "([model_benchmark.json](model_benchmark.json)).", "", *self.notes("speed")]
        lines += ["## Depth-camera-sized clouds", "", *self.large(pred["large_clouds"]), "",
                  f"Measured by {provenance(pred)} ([predict_benchmark.json](predict_benchmark.json)).", "",
                  *self.notes("large")]
        lines += self.details()
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
    def speed(pred: dict, bench: dict) -> list[str]:
        train, cpu = bench["train_step"], bench.get("train_step_cpu_preset", {})
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
