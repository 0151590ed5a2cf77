"""Where a training step's time goes on one CPU core, and how close it is to the core's matmul peak.

    python benchmarks/train_step.py [--train data/unimodal/train512] [--presets cpu,cpu-multimodal] [--steps 60]
                                    [--threads 1] [--data-workers 0 1] [--levers] [--out FILE]

Prints one JSON object. For each preset (the shipped recipe of each kind of task): seconds per step split into
data (the next batch from the run's own DataLoader), forward (the loss), backward, optimizer (clipping, AdamW, the
EMA) and the rest; the FLOPs of a step (torch's counter); and so the fraction of this core's float32 and bfloat16
matmul peaks, measured in the same run (a timed 1024 x 1024 torch.mm). With --levers, the step alone (no data) under
each speed lever, interleaved round by round so that a disturbance lands on all of them alike: bf16 autocast,
torch.compile, the math attention kernel in place of the one torch picks (flash on CPU), and batch sizes
8 / 32. Without --train, random clouds stand in for the demos (no data phase).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
import time
from pathlib import Path

import numpy as np
import torch
from torch.utils.data import DataLoader
from torch.nn.attention import SDPBackend, sdpa_kernel

sys.path.insert(0, str(Path(__file__).resolve().parent))

from model import ATTENTION_FLOPS, best_time  # noqa: E402  (benchmarks/model.py)
from tax3d import config as cfg  # noqa: E402
from tax3d import provenance  # noqa: E402
from tax3d import kept  # noqa: E402
from tax3d.data.dataset import DemoDataset  # noqa: E402
from tax3d.model.tax3d import Tax3D  # noqa: E402
from tax3d.training.batches import EpochItems, StepBatches  # noqa: E402
from tax3d.training.tax3d import TrainingLoss, ema_decay  # noqa: E402

PHASES = ("data", "forward", "backward", "optimizer", "rest")


def matmul_peak(dtype: torch.dtype, n: int = 1024, repeats: int = 7) -> float:
    a, b = torch.randn(n, n, dtype=dtype), torch.randn(n, n, dtype=dtype)
    torch.mm(a, b)
    return 2 * n**3 / best_time(lambda: torch.mm(a, b), repeats)


def random_batches(config: cfg.Config):
    B, N, M = config.train.batch_size, config.data.num_action_points, config.data.num_anchor_points
    gen = torch.Generator().manual_seed(0)
    while True:
        yield {"action": torch.randn(B, N, 3, generator=gen), "anchor": torch.randn(B, M, 3, generator=gen),
               "target": torch.randn(B, N, 3, generator=gen)}


def demo_batches(config: cfg.Config, train: list[str]):
    d = config.data
    dataset = DemoDataset(train, config.model.variant, train=True, rotate=d.rotate, num_action_points=d.num_action_points,
                          num_anchor_points=d.num_anchor_points, train_size=d.train_size, seed=0, subsets=d.subsets,
                          grip_weight=d.grip_weight)
    loader = DataLoader(EpochItems(dataset), batch_sampler=StepBatches(len(dataset), config.train.batch_size, 0),
                        num_workers=config.train.num_workers, persistent_workers=config.train.num_workers > 0)
    return iter(loader)


class Step:
    """One training step of `config`, as the loop in tax3d.training.loop makes it, with a timer around each phase."""

    def __init__(self, config: cfg.Config, batches, bf16: bool = False, compiled: bool = False,
                 attention: SDPBackend | None = None):
        torch.manual_seed(0)
        self.attention = attention  # a scaled_dot_product_attention kernel forced for the step (None: torch's pick)
        self.config, self.batches = config, batches
        self.model = Tax3D(config)
        self.ema = [p.detach().clone() for p in self.model.net.parameters()]
        self.optimizer = torch.optim.AdamW(self.model.parameters(), lr=config.train.lr, weight_decay=1e-5)
        self.loss = TrainingLoss(self.model, torch.bfloat16 if bf16 else None, torch.device("cpu"))
        if compiled:
            self.model.net = torch.compile(self.model.net)
        self.gen = torch.Generator().manual_seed(0)
        self.times = {k: [] for k in PHASES}
        self.step = 0

    def __call__(self) -> dict:
        if self.attention is None:
            return self._step()
        with sdpa_kernel(self.attention):
            return self._step()

    def _step(self) -> dict:
        c, marks = self.config.train, [time.perf_counter()]
        batch = next(self.batches)
        marks.append(time.perf_counter())
        t = self.model.diffusion.sample_timesteps(c.batch_size, generator=self.gen)
        noise = torch.randn(batch["target"].shape, generator=self.gen)
        losses = self.loss(batch, t, noise)
        marks.append(time.perf_counter())
        self.optimizer.zero_grad(set_to_none=True)
        losses["loss"].backward()
        marks.append(time.perf_counter())
        torch.nn.utils.clip_grad_norm_(self.model.parameters(), c.grad_clip)
        self.optimizer.step()
        with torch.no_grad():
            for e, p in zip(self.ema, self.model.net.parameters()):
                e.lerp_(p, 1.0 - ema_decay(self.step, c.ema))
        marks.append(time.perf_counter())
        float(losses["loss"].detach())  # the loop's logging reads the loss every step
        marks.append(time.perf_counter())
        self.step += 1
        seconds = dict(zip(PHASES, np.diff(marks)))
        for k, v in seconds.items():
            self.times[k].append(v)
        return seconds

    def flops(self) -> int:
        from torch.utils.flop_counter import FlopCounterMode

        batch = next(self.batches)
        t = self.model.diffusion.sample_timesteps(self.config.train.batch_size, generator=self.gen)
        with FlopCounterMode(display=False, custom_mapping=ATTENTION_FLOPS) as counter:
            self.loss(batch, t, torch.randn(batch["target"].shape, generator=self.gen))["loss"].backward()
        return counter.get_total_flops()


def profile(config: cfg.Config, train: list[str] | None, steps: int, peaks: dict) -> dict:
    batches = demo_batches(config, train) if train else random_batches(config)
    step = Step(config, batches)
    for _ in range(10):  # warm-up: the allocator, the data worker's start
        step()
    step.times = {k: [] for k in PHASES}
    for _ in range(steps):
        step()
    seconds = {k: float(np.median(v)) for k, v in step.times.items()}
    total = float(np.median(np.sum([step.times[k] for k in PHASES], axis=0)))
    flops = step.flops()
    c, d = config.train, config.data
    return {"shape": {"hidden": config.model.hidden_size, "depth": config.model.depth, "points": [d.num_action_points,
            d.num_anchor_points], "batch": c.batch_size, "data_workers": c.num_workers, "demos": bool(train)},
            "step_seconds": total, "steps_per_second": 1 / total, "phase_seconds": seconds,
            "phase_share": {k: v / total for k, v in seconds.items()}, "flops_per_step": flops,
            "flop_rate": flops / total, "fraction_of_fp32_peak": flops / total / peaks["fp32"],
            "fraction_of_bf16_peak": flops / total / peaks["bf16"]}


def top_ops(config: cfg.Config, steps: int = 10, top: int = 8) -> list[dict]:
    """The operators that take the most time in `steps` steps (torch.profiler, self CPU time), with their share."""
    from torch.profiler import ProfilerActivity, profile as torch_profile

    step = Step(config, random_batches(config))
    for _ in range(3):
        step()
    with torch_profile(activities=[ProfilerActivity.CPU]) as prof:
        for _ in range(steps):
            step()
    events = sorted(prof.key_averages(), key=lambda e: e.self_cpu_time_total, reverse=True)
    total = sum(e.self_cpu_time_total for e in events)
    return [{"op": e.key, "share": e.self_cpu_time_total / total} for e in events[:top]]


def threads(config: cfg.Config, rounds: int) -> dict:
    """One run on two threads against one thread: two one-thread runs side by side get twice the one-thread rate."""
    step = Step(config, random_batches(config))
    times = {1: [], 2: []}
    for n in times:
        torch.set_num_threads(n)
        step()
    for _ in range(rounds):
        for n in times:
            torch.set_num_threads(n)
            start = time.perf_counter()
            step()
            times[n].append(time.perf_counter() - start)
    torch.set_num_threads(1)
    one, two = float(np.median(times[1])), float(np.median(times[2]))
    return {"step_seconds_1_thread": one, "step_seconds_2_threads": two, "speedup_2_threads": one / two}


def levers(config: cfg.Config, rounds: int) -> dict:
    """Seconds per step without data (random batches), each lever interleaved with the others round by round."""
    def with_batch(b):
        return dataclasses.replace(config, train=dataclasses.replace(config.train, batch_size=b))

    steps = {"fp32": Step(config, random_batches(config)), "bf16": Step(config, random_batches(config), bf16=True),
             "compile": Step(config, random_batches(config), compiled=True),
             "math_attention": Step(config, random_batches(config), attention=SDPBackend.MATH),
             "batch8": Step(with_batch(8), random_batches(with_batch(8))),
             "batch32": Step(with_batch(32), random_batches(with_batch(32)))}
    for step in steps.values():
        for _ in range(5):  # warm-up; torch.compile traces here
            step()
    times = {k: [] for k in steps}
    for _ in range(rounds):
        for name, step in steps.items():
            start = time.perf_counter()
            step()
            times[name].append(time.perf_counter() - start)
    out = {k: {"step_seconds": float(np.median(v))} for k, v in times.items()}
    base = out["fp32"]["step_seconds"]
    for name, batch in (("fp32", 16), ("bf16", 16), ("compile", 16), ("math_attention", 16), ("batch8", 8),
                        ("batch32", 32)):
        out[name]["speedup"] = base / out[name]["step_seconds"]
        out[name]["samples_per_second_ratio"] = (batch / out[name]["step_seconds"]) / (16 / base)
    out["rounds"] = rounds
    return out


def emit(result: dict, out: Path | None) -> None:
    """Print the kept JSON (kind "train-step-benchmark") and, with --out, write it to that file as well."""
    text = json.dumps(kept.stamp("train-step-benchmark", 1, result), indent=2)
    if out:
        out.write_text(text + "\n")
    print(text)

def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--train", nargs="*", default=None, help="training demo folders (default: random clouds)")
    parser.add_argument("--presets", default="cpu,cpu-multimodal")
    parser.add_argument("--steps", type=int, default=60)
    parser.add_argument("--threads", type=int, default=1)
    parser.add_argument("--data-workers", type=int, nargs="*", default=None,
                        help="profile each preset with each of these data-worker counts (default: the preset's)")
    parser.add_argument("--levers", action="store_true")
    parser.add_argument("--rounds", type=int, default=30)
    parser.add_argument("--out", type=Path, default=None)
    args = parser.parse_args(argv)
    torch.set_num_threads(args.threads)
    peaks = {"fp32": matmul_peak(torch.float32), "bf16": matmul_peak(torch.bfloat16)}
    result = {"command": "python benchmarks/train_step.py " + " ".join(sys.argv[1:] if argv is None else argv),
              "machine": provenance.machine(), "date": provenance.today(), "threads": args.threads,
              "matmul_peak_flops": peaks, "presets": {}}
    for name in args.presets.split(","):
        for workers in args.data_workers or [None]:
            config = cfg.preset(name)
            if workers is not None:
                config.train.num_workers = workers
            key = name if workers is None else f"{name}-{workers}workers"
            result["presets"][key] = profile(config, args.train, args.steps, peaks)
    if args.levers:
        first = cfg.preset(args.presets.split(",")[0])
        result["levers"] = levers(first, args.rounds)
        result["top_ops"] = top_ops(first)
        result["two_threads"] = threads(first, args.rounds)
    result["peaks_again"] = {"fp32": matmul_peak(torch.float32), "bf16": matmul_peak(torch.bfloat16)}
    emit(result, args.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
