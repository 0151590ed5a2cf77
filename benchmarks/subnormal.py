"""A training step with and without subnormal floats flushed to zero, on a run's own weights and demos.

    python benchmarks/subnormal.py --run RUN/last --train DIR [--rounds 10] [--out FILE]

Subnormal floats (below 1.2e-38 in float32) take the CPU's slow path. A run's weights, Adam state and activations can
fill with them as training goes on, so the same network steps at different speeds on different runs. This loads a
run's checkpoint (`last/`) and times the forward and backward pass of its own loss on batches of its demos, on one
core, interleaving the two settings round by round. Prints one JSON object (kind "train-step-benchmark").
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
import torch

sys.path.insert(0, str(Path(__file__).resolve().parent))

from train_step import demo_batches, emit  # noqa: E402
from tax3d import config as cfg  # noqa: E402
from tax3d import provenance  # noqa: E402
from tax3d.model.tax3d import Tax3D  # noqa: E402
from tax3d.training.tax3d import TrainingLoss  # noqa: E402


def timed_steps(run: Path, train: list[str], rounds: int) -> dict:
    model = Tax3D.from_pretrained(run)
    config = cfg.load(run / "config.json")
    config.train.num_workers = 0
    batches = demo_batches(config, train)
    loss = TrainingLoss(model, None, torch.device("cpu"))
    gen = torch.Generator().manual_seed(0)
    times = {"subnormals": [], "flushed": []}
    for round_ in range(rounds + 1):  # the first round warms up
        for name, flush in (("subnormals", False), ("flushed", True)):
            torch.set_flush_denormal(flush)
            batch = next(batches)
            t = model.diffusion.sample_timesteps(config.train.batch_size, generator=gen)
            noise = torch.randn(batch["target"].shape, generator=gen)
            start = time.perf_counter()
            model.zero_grad(set_to_none=True)
            loss(batch, t, noise)["loss"].backward()
            if round_:
                times[name].append(time.perf_counter() - start)
    torch.set_flush_denormal(False)
    out = {k: float(np.median(v)) for k, v in times.items()}
    return {"forward_backward_seconds": out, "speedup_flushed": out["subnormals"] / out["flushed"], "rounds": rounds}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--run", type=Path, required=True, help="a checkpoint folder of a training run (RUN/last)")
    parser.add_argument("--train", nargs="+", required=True, help="the run's training demo folders")
    parser.add_argument("--rounds", type=int, default=10)
    parser.add_argument("--out", type=Path, default=None)
    args = parser.parse_args(argv)
    if not (args.run / "config.json").is_file():
        print(f"error: --run {args.run}: no config.json; expected a checkpoint folder such as RUN/last", file=sys.stderr)
        return 2
    torch.set_num_threads(1)
    result = {"command": "python benchmarks/subnormal.py " + " ".join(sys.argv[1:] if argv is None else argv),
              "machine": provenance.machine(), "date": provenance.today(), "threads": 1, "run": str(args.run),
              **timed_steps(args.run, args.train, args.rounds)}
    emit(result, args.out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
