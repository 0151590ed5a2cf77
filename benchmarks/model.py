"""Training-step time and FLOP rate at the paper's configuration, and prediction latency and RMSE of 100 vs 10 steps.

    python benchmarks/model.py [--threads 1] [--checkpoint checkpoints/tax3d-cd-official-simple] [--samples 3]
                               [--parts train,predict,large,precision] [--rounds 9]

Prints one JSON object. The FLOP rate is compared with this machine's float32 matmul peak measured in the same run
(a timed 2048 x 2048 torch.mm), so the ratio holds on a shared, noisy machine. The prediction part uses the shipped
checkpoint on the official `val` split and is skipped, with a note, where the data is absent.
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np
import torch
from torch.utils.flop_counter import FlopCounterMode, sdpa_backward_flop_count, sdpa_flop_count

from tax3d import config as cfg
from tax3d import kept
from tax3d.data.dataset import demo_files
from tax3d.data.format import load_demo
from tax3d.metrics import min_of_samples_rmse, rmse
from tax3d.model.tax3d import Tax3D

ROOT = Path(__file__).resolve().parents[1]
OFFICIAL_VAL = ROOT.parent / "shared" / "data" / "tax3d-official" / "hangproccloth-simple" / "val"


def best_time(fn, repeats: int) -> float:
    """The fastest of `repeats` calls, in seconds (the least disturbed by other processes)."""
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return min(times)


def matmul_peak(n: int = 2048, repeats: int = 5) -> float:
    a, b = torch.randn(n, n), torch.randn(n, n)
    torch.mm(a, b)
    return 2 * n**3 / best_time(lambda: torch.mm(a, b), repeats)


def _attention_flops(q, k, v, *args, **kwargs) -> int:
    return sdpa_flop_count(q, k, v)


def _attention_backward_flops(grad_out, q, k, v, *args, **kwargs) -> int:
    return sdpa_backward_flop_count(grad_out, q, k, v)


# torch's counter has no formula for the CPU flash-attention kernels; the standard ones (2 matmuls forward, 4 backward)
ATTENTION_FLOPS = {
    torch.ops.aten._scaled_dot_product_flash_attention_for_cpu: _attention_flops,
    torch.ops.aten._scaled_dot_product_flash_attention_for_cpu_backward: _attention_backward_flops,
}


def model_and_batch(config: cfg.Config) -> tuple[Tax3D, torch.optim.Optimizer, dict]:
    """A seeded TAX3D model of `config`, its AdamW optimizer and one random batch of the configured sizes."""
    torch.manual_seed(0)
    model = Tax3D(config)
    optimizer = torch.optim.AdamW(model.parameters(), lr=1e-4, weight_decay=1e-5)
    B, N = config.train.batch_size, config.data.num_action_points
    batch = {"action": torch.randn(B, N, 3), "anchor": torch.randn(B, config.data.num_anchor_points, 3),
             "target": torch.randn(B, N, 3)}
    return model, optimizer, batch


def training_step(repeats: int, config: cfg.Config | None = None) -> dict:
    """One AdamW step of TAX3D-CD (default: the paper's configuration, batch 16, 512 action + 512 anchor points)."""
    config = config or cfg.paper()
    model, optimizer, batch = model_and_batch(config)

    def step():
        losses = model.loss(batch)
        optimizer.zero_grad(set_to_none=True)
        losses["loss"].backward()
        torch.nn.utils.clip_grad_norm_(model.parameters(), 1.0)
        optimizer.step()

    step()
    with FlopCounterMode(display=False, custom_mapping=ATTENTION_FLOPS) as counter:
        losses = model.loss(batch)
        losses["loss"].backward()
    flops = counter.get_total_flops()
    by_op = {str(op): n for op, n in counter.get_flop_counts()["Global"].items()}
    seconds = best_time(step, repeats)
    return {"seconds": seconds, "flops": flops, "flop_rate": flops / seconds, "flops_by_op": by_op}


def cpu_preset(repeats: int) -> dict:
    """The cpu preset's step with 1 and 2 torch threads, and the time to make one batch of samples (FPS)."""
    config = cfg.cpu()
    result = {}
    threads = torch.get_num_threads()
    for n in (1, 2):
        torch.set_num_threads(n)
        result[f"step_seconds_{n}_threads"] = training_step(repeats, config)["seconds"]
    torch.set_num_threads(threads)
    train_dir = OFFICIAL_VAL.parent / "train"
    if train_dir.is_dir():
        from tax3d.data.dataset import DemoDataset

        dataset = DemoDataset(train_dir, "cd", train=True, rotate=config.data.rotate,
                              num_action_points=config.data.num_action_points,
                              num_anchor_points=config.data.num_anchor_points, train_size=config.data.train_size)
        B = config.train.batch_size
        result["batch_data_seconds"] = best_time(lambda: [dataset[i] for i in range(B)], repeats)
    return result


def precision_steps(rounds: int) -> dict:
    """Seconds per training step in float32 and under bfloat16 autocast (what `--train.precision bf16` does), for
    the cpu and paper networks, interleaved round by round so that a disturbance lands on both alike."""
    result = {}
    for name, config in (("cpu", cfg.cpu()), ("paper", cfg.paper())):
        model, optimizer, batch = model_and_batch(config)

        def step(bf16: bool):
            with torch.autocast("cpu", dtype=torch.bfloat16, enabled=bf16):
                losses = model.loss(batch)
            optimizer.zero_grad(set_to_none=True)
            losses["loss"].backward()
            optimizer.step()

        times = {"fp32": [], "bf16": []}
        for label in times:
            step(label == "bf16")
        for _ in range(rounds):
            for label in times:
                start = time.perf_counter()
                step(label == "bf16")
                times[label].append(time.perf_counter() - start)
        fp32, bf16 = float(np.median(times["fp32"])), float(np.median(times["bf16"]))
        result[name] = {"fp32_seconds": fp32, "bf16_seconds": bf16, "speedup_bf16": fp32 / bf16}
    result["rounds"] = rounds
    return result


SAMPLERS = (("ddpm_100", 100, "ddpm"), ("ddpm_10", 10, "ddpm"), ("ddim_10", 10, "ddim"))


def latencies(model: Tax3D, demo: dict, rounds: int) -> dict:
    """Seconds per `predict` call of each sampler on one scene: the fastest and the median of `rounds` rounds.

    Rounds interleave the samplers (one call of each per round, after a warm-up call of each), so a disturbance
    from another process lands on all of them alike rather than on whichever sampler ran during it."""
    calls = {name: (lambda s=steps, k=sampler: model.predict(demo["action_pc"], demo["anchor_pc"], steps=s,
                                                             sampler=k, seed=0))
             for name, steps, sampler in SAMPLERS}
    for call in calls.values():
        call()
    times = {name: [] for name in calls}
    for _ in range(rounds):
        for name, call in calls.items():
            start = time.perf_counter()
            call()
            times[name].append(time.perf_counter() - start)
    return {name: {"latency_s": float(np.median(ts)), "latency_min_s": min(ts)} for name, ts in times.items()}


def prediction(checkpoint: Path, samples: int, rounds: int) -> dict:
    model = Tax3D.from_pretrained(checkpoint)
    result = {"checkpoint": str(checkpoint.relative_to(ROOT) if checkpoint.is_relative_to(ROOT) else checkpoint)}
    if not OFFICIAL_VAL.is_dir():
        result["note"] = f"official val split not found at {OFFICIAL_VAL}: latency on a synthetic scene, no RMSE"
        demos = [{"action_pc": np.random.default_rng(0).normal(size=(580, 3)),
                  "anchor_pc": np.random.default_rng(1).normal(size=(1301, 3)), "flow": None}]
    else:
        demos = [load_demo(p) for p in demo_files(OFFICIAL_VAL)]
    first = demos[0]
    result.update(latencies(model, first, rounds))
    if first["flow"] is not None:
        truth = [d["action_pc"] + d["flow"] for d in demos]
        for name, steps, sampler in SAMPLERS:
            goals = model.predict_scenes([(d["action_pc"], d["anchor_pc"]) for d in demos], num_samples=samples,
                                         steps=steps, sampler=sampler, seed=0)
            result[name]["rmse_min_of_samples"] = float(np.mean([min_of_samples_rmse(g, t)
                                                                 for g, t in zip(goals, truth)]))
            result[name]["rmse_mean"] = float(np.mean([rmse(g, t).mean() for g, t in zip(goals, truth)]))
    # the median latencies give the speed-up; the fastest calls give a second, less disturbed estimate
    result["speedup_10_vs_100"] = result["ddpm_100"]["latency_s"] / result["ddpm_10"]["latency_s"]
    result["speedup_10_vs_100_fastest"] = result["ddpm_100"]["latency_min_s"] / result["ddpm_10"]["latency_min_s"]
    if "rmse_min_of_samples" in result["ddpm_100"]:
        base = result["ddpm_100"]["rmse_min_of_samples"]
        for name in ("ddpm_10", "ddim_10"):
            result[f"rmse_ratio_{name}_vs_100"] = result[name]["rmse_min_of_samples"] / base
    result["demos"], result["samples_per_demo"], result["action_points"] = len(demos), samples, len(first["action_pc"])
    result["latency_rounds"] = rounds
    return result


def large_clouds(checkpoint: Path, samples: int, rounds: int, points: int = 20_000) -> dict:
    """Prediction on a depth-camera-sized action cloud (the first val cloth resampled to `points` points near its
    vertices) with the 10-step sampler, and the goal RMSE on the whole val cloths with the network on at most the
    training number of points (the default) against every point."""
    model = Tax3D.from_pretrained(checkpoint)
    if not OFFICIAL_VAL.is_dir():
        return {"note": f"official val split not found at {OFFICIAL_VAL}"}
    demos = [load_demo(p) for p in demo_files(OFFICIAL_VAL)]
    rng = np.random.default_rng(0)
    cloth = demos[0]["action_pc"]
    dense = cloth[rng.integers(len(cloth), size=points)] + rng.normal(scale=0.02, size=(points, 3))
    call = lambda: model.predict(dense, demos[0]["anchor_pc"], steps=10, sampler="ddpm", seed=0)  # noqa: E731
    call()
    times = []
    for _ in range(rounds):
        start = time.perf_counter()
        call()
        times.append(time.perf_counter() - start)
    truth = [d["action_pc"] + d["flow"] for d in demos]
    scenes = [(d["action_pc"], d["anchor_pc"]) for d in demos]
    result = {"action_points": points, "network_points": model.config.data.num_action_points, "sampler": "ddpm_10",
              "latency_s": float(np.median(times)), "latency_min_s": float(min(times)), "rounds": rounds,
              "demos": len(demos), "samples_per_demo": samples}
    for name, max_points in (("sampled", None), ("every_point", 0)):
        goals = model.predict_scenes(scenes, num_samples=samples, seed=0, max_points=max_points)
        result[f"rmse_{name}"] = float(np.mean([min_of_samples_rmse(g, t) for g, t in zip(goals, truth)]))
        result[f"rmse_mean_{name}"] = float(np.mean([rmse(g, t[None]).mean() for g, t in zip(goals, truth)]))
    # min over the samples of each demo (as training validates), and the mean over them (as `tax3d eval` scores)
    result["rmse_ratio_sampled_vs_every_point"] = result["rmse_sampled"] / result["rmse_every_point"]
    result["rmse_mean_ratio_sampled_vs_every_point"] = result["rmse_mean_sampled"] / result["rmse_mean_every_point"]
    return result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--threads", type=int, default=0, help="torch threads (0: torch's default)")
    parser.add_argument("--checkpoint", type=Path, default=ROOT / "checkpoints" / "tax3d-cd-official-simple")
    parser.add_argument("--samples", type=int, default=3, help="samples per val demo for the RMSE")
    parser.add_argument("--repeats", type=int, default=5, help="timed calls per training-step measurement")
    parser.add_argument("--rounds", type=int, default=9, help="interleaved rounds of prediction-latency calls")
    parser.add_argument("--parts", default="train,predict", help="comma-separated: train (training step, FLOP "
                        "rate, cpu preset), predict (latency and RMSE), large (20,000 action points), precision "
                        "(float32 against bfloat16 autocast)")
    args = parser.parse_args()
    if args.threads > 0:
        torch.set_num_threads(args.threads)

    parts = set(args.parts.split(","))
    if not parts or parts - {"train", "predict", "large", "precision"}:
        print(f"error: --parts {args.parts!r}: expected a comma-separated list of train, predict, large, precision",
              file=sys.stderr)
        sys.exit(2)
    out = {
        "command": "python " + " ".join(sys.argv),
        "machine": f"{platform.machine()}, {os.cpu_count()} cores, {torch.get_num_threads()} torch threads, "
                   f"torch {torch.__version__}",
        "date": datetime.date.today().isoformat(),
    }
    if "train" in parts:
        peak = matmul_peak()
        train = training_step(args.repeats)
        out["matmul_peak_gflops"] = peak / 1e9
        out["train_step"] = {"config": "paper: TAX3D-CD, hidden 128, depth 5, batch 16, 512 + 512 points",
                             "seconds": train["seconds"], "gflop": train["flops"] / 1e9,
                             "gflops": train["flop_rate"] / 1e9, "fraction_of_peak": train["flop_rate"] / peak,
                             "gflop_by_op": {op: n / 1e9 for op, n in train["flops_by_op"].items()}}
        out["train_step_cpu_preset"] = cpu_preset(args.repeats)
    if "predict" in parts:
        if args.checkpoint.is_dir():
            out["predict"] = prediction(args.checkpoint, args.samples, args.rounds)
        else:
            out["predict"] = {"note": f"no checkpoint at {args.checkpoint}"}
    if "precision" in parts:
        out["precision"] = precision_steps(args.rounds)
    if "large" in parts:
        out["large_clouds"] = large_clouds(args.checkpoint, args.samples, args.rounds)
    print(json.dumps(kept.stamp("model-benchmark", 1, out)))


if __name__ == "__main__":
    main()
