"""Training under torchrun (2 CPU processes over gloo) against one process, resuming, bad input, and bf16 autocast."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import torch
from safetensors.torch import load_file

from tax3d.checkpoint import STATE_NAME
from tax3d.training import batches, distributed
from tax3d.training import tax3d as learner
from tax3d.cli import main
from tax3d.data.dataset import make_sample
from tax3d.data.format import save_demo
from tax3d.errors import UsageError
from tax3d.model.diffusion import GaussianDiffusion
from tax3d.model.tax3d import Tax3D

from tests.conftest import synthetic_demo, tiny_model
from tests.conftest import TINY, read_log

pytestmark = pytest.mark.skipif(
    not (torch.distributed.is_available() and torch.distributed.is_gloo_available()),
    reason="this torch has no torch.distributed with the gloo backend")

ROOT = Path(__file__).resolve().parents[1]
LAUNCH_ENV = ("WORLD_SIZE", "RANK", "LOCAL_RANK", "LOCAL_WORLD_SIZE", "MASTER_ADDR", "MASTER_PORT")
# Both runs compute the same global batch with the same timesteps and noise (every rank draws the global batch's
# and keeps its rows); they differ only in float32 summation order (per-rank means averaged by an all-reduce,
# gradients all-reduced in buckets), about 1e-7 relative per step. 1e-5 leaves room for a few Adam steps and is
# far below what a wrong sample or a wrong noise draw changes (order 1).
RTOL = 1e-5


def torchrun(*argv: str, nproc: int = 2) -> subprocess.CompletedProcess:
    env = {k: v for k, v in os.environ.items() if k not in LAUNCH_ENV}
    env["OMP_NUM_THREADS"] = "1"
    command = [sys.executable, "-m", "torch.distributed.run", "--standalone", "--nproc_per_node", str(nproc),
               "-m", "tax3d.cli", "train", *argv]
    return subprocess.run(command, cwd=ROOT, env=env, capture_output=True, text=True, timeout=600)


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """The same 2-step run in one process and in two under torchrun, with the weights each ends with."""
    root = tmp_path_factory.mktemp("ddp")
    folder = root / "demos"
    folder.mkdir()
    for i in range(2):
        save_demo(folder / f"demo_{i}.npz", synthetic_demo(i))
    args = [*TINY, "--data.train", str(folder), "--data.val", str(folder), "--train.val_every", "2",
            "--data.rotate", "True"]
    assert main(["train", *args, "--out", str(root / "one"), "--train.steps", "2"]) == 0
    two = torchrun(*args, "--out", str(root / "two"), "--train.steps", "2")
    assert two.returncode == 0, two.stderr[-4000:]
    shutil.copytree(root / "two", root / "two_at_step_2")  # test_resume_under_torchrun continues "two"
    weights = {name: load_file(root / name / "last" / "model.safetensors") for name in ("one", "two")}
    return root, args, two, weights


def assert_close_logs(a: list[dict], b: list[dict]) -> None:
    assert [r["step"] for r in a] == [r["step"] for r in b]
    for x, y in zip(a, b):
        for key in ("loss", "mse", "vb", "lr"):
            assert y[key] == pytest.approx(x[key], rel=RTOL), (x["step"], key)


def test_two_processes_write_one_checkpoint_from_rank_0(runs):
    root, _, two, _ = runs
    out = root / "two"
    assert sorted(p.name for p in out.iterdir()) == ["best", "config.json", "demos.json", "last", "log.jsonl", "summary.json"]
    assert [r["step"] for r in read_log(out)] == [1, 2]  # one writer: no line twice
    assert torch.load(out / "last" / STATE_NAME, weights_only=True)["step"] == 2
    model = Tax3D.from_pretrained(out / "last")
    assert model.config.train.batch_size == 8  # the global batch, as in one process
    assert "Traceback" not in two.stderr


def test_two_processes_match_one_process(runs):
    root, _, _, weights = runs
    one, two = read_log(root / "one")[:2], read_log(root / "two")[:2]  # before test_resume adds steps
    assert two[0]["loss"] == pytest.approx(one[0]["loss"], rel=RTOL)
    assert_close_logs(one, two)
    assert two[-1]["val_rmse"] == pytest.approx(one[-1]["val_rmse"], rel=1e-4)
    for key, value in weights["one"].items():
        torch.testing.assert_close(weights["two"][key], value, rtol=1e-4, atol=1e-6)


def test_resume_under_torchrun(runs):
    root, args, _, _ = runs
    assert main(["train", *args, "--out", str(root / "one"), "--train.steps", "4", "--resume"]) == 0
    resumed = torchrun(*args, "--out", str(root / "two"), "--train.steps", "4", "--resume")
    assert resumed.returncode == 0, resumed.stderr[-4000:]
    assert resumed.stderr.count("at step 2") == 1  # rank 0 alone says so
    one, two = read_log(root / "one"), read_log(root / "two")
    assert [r["step"] for r in two] == [1, 2, 3, 4]
    assert_close_logs(one, two)
    assert torch.load(root / "two" / "last" / STATE_NAME, weights_only=True)["step"] == 4


def test_resume_with_another_number_of_processes(tmp_path, runs):
    root, args, _, _ = runs
    assert main(["train", *args, "--out", str(tmp_path / "whole"), "--train.steps", "4"]) == 0
    shutil.copytree(root / "two_at_step_2", tmp_path / "fewer")
    assert main(["train", *args, "--out", str(tmp_path / "fewer"), "--train.steps", "4", "--resume"]) == 0
    assert_close_logs(read_log(tmp_path / "whole"), read_log(tmp_path / "fewer"))


def test_batch_size_not_divisible_by_the_world_size(tmp_path, runs, monkeypatch, capsys):
    root, args, _, _ = runs
    bad = [*args, "--out", str(tmp_path / "bad"), "--train.steps", "2", "--train.batch_size", "7"]
    for name, value in dict(WORLD_SIZE="2", RANK="1", LOCAL_RANK="1", MASTER_ADDR="127.0.0.1",
                            MASTER_PORT="29500").items():
        monkeypatch.setenv(name, value)
    assert main(["train", *bad]) == 2
    err = capsys.readouterr().err.strip()
    assert "--train.batch_size 7" in err and "multiple of 2" in err and len(err.splitlines()) == 1, err
    assert not (tmp_path / "bad").exists()
    for name in LAUNCH_ENV:
        monkeypatch.delenv(name, raising=False)
    # torchrun itself: a process prints the line and exits with 2; torchrun reports that and fails. Once one
    # worker has failed, torchrun stops the other, which may or may not have printed its line by then.
    failed = torchrun(*bad)
    assert failed.returncode != 0
    assert failed.stderr.count("tax3d train: error: --train.batch_size 7: not divisible") in (1, 2)
    assert "src/tax3d" not in failed.stderr  # torchrun prints its own traceback; none of ours
    assert "exitcode  : 2" in failed.stderr


@pytest.mark.parametrize("environ, option", [
    (dict(WORLD_SIZE="2", LOCAL_RANK="0", MASTER_ADDR="h", MASTER_PORT="1"), "RANK"),
    (dict(WORLD_SIZE="2", RANK="0", LOCAL_RANK="0"), "MASTER_ADDR"),
    (dict(WORLD_SIZE="two", RANK="0", LOCAL_RANK="0", MASTER_ADDR="h", MASTER_PORT="1"), "WORLD_SIZE"),
    (dict(WORLD_SIZE="2", RANK="2", LOCAL_RANK="0", MASTER_ADDR="h", MASTER_PORT="1"), "RANK=2"),
])
def test_a_broken_launch_environment(environ, option):
    with pytest.raises(UsageError, match=option) as err:
        distributed.from_env(environ)
    assert len(str(err.value).splitlines()) == 1


def test_options_that_make_no_sense_under_torchrun():
    world = distributed.World(rank=1, size=2, local_rank=1)
    assert distributed.from_env({}) == distributed.World() and not distributed.World().distributed
    assert distributed.rank_device(world, "cpu", torch.device("cpu")) == torch.device("cpu")
    with pytest.raises(UsageError, match=r"--train.device cuda:1: under torchrun"):
        distributed.rank_device(world, "cuda:1", torch.device("cuda:1"))
    with pytest.raises(UsageError, match="--train.batch_size 9"):
        distributed.check_batch_size(distributed.World(0, 4, 0), 9)
    assert [distributed.World(r, 4, r).share(8) for r in range(4)] == [slice(0, 2), slice(2, 4), slice(4, 6),
                                                                       slice(6, 8)]


def test_ranks_split_the_batches_of_one_process():
    whole = batches.StepBatches(10, 6, seed=3, start_step=4)
    ranks = [batches.StepBatches(10, 6, seed=3, start_step=4, rank=r, world_size=3) for r in range(3)]
    streams = [iter(s) for s in (whole, *ranks)]
    for _ in range(5):
        batch, *shares = (next(s) for s in streams)
        assert [len(s) for s in shares] == [2, 2, 2] and sum(shares, []) == batch


# --- bf16 ------------------------------------------------------------------------------------------------------


def test_bf16_on_cpu_trains_with_finite_losses(tmp_path, runs):
    root, args, _, _ = runs
    out = tmp_path / "bf16"
    assert main(["train", *args, "--out", str(out), "--train.steps", "3", "--train.precision", "bf16"]) == 0
    log = read_log(out)
    assert [r["step"] for r in log] == [1, 2, 3]
    assert all(np.isfinite(r[k]) for r in log for k in ("loss", "mse", "vb", "val_rmse") if k in r)
    assert Tax3D.from_pretrained(out / "last").config.train.precision == "bf16"


def test_bf16_on_cpu_matches_fp32_within_bfloat16_rounding(tmp_path, runs):
    """The same seeded run under bf16 autocast and in fp32: the same batches and noise, so the losses differ only by
    bfloat16's rounding of the network (8 bits of mantissa)."""
    root, args, _, _ = runs
    logs = {}
    for precision in ("fp32", "bf16"):
        out = tmp_path / precision
        assert main(["train", *args, "--out", str(out), "--train.steps", "3", "--train.precision", precision]) == 0
        logs[precision] = read_log(out)
    assert [r["step"] for r in logs["bf16"]] == [r["step"] for r in logs["fp32"]] == [1, 2, 3]
    for fp32, bf16 in zip(logs["fp32"], logs["bf16"]):
        assert bf16["mse"] == pytest.approx(fp32["mse"], rel=0.05), fp32["step"]
    # step 1 is equal (DiT's zero-initialised output layer); after it the network did run in bfloat16
    assert logs["bf16"][-1]["mse"] != logs["fp32"][-1]["mse"]


def test_bf16_autocasts_the_network_and_keeps_the_diffusion_maths_fp32(monkeypatch):
    model = tiny_model("cd").train()  # random weights: DiT's zero-initialised output layer would hide the casts
    demo = synthetic_demo(0)
    batch = torch.utils.data.default_collate([
        make_sample(demo["action_pc"], demo["anchor_pc"], demo["action_pc"] + demo["flow"], "cd",
                    torch.Generator().manual_seed(i), 16, 24) for i in range(4)])
    t = torch.tensor([0, 1, 50, 99])
    noise = torch.randn(batch["target"].shape, generator=torch.Generator().manual_seed(0))
    seen = {}
    model.net.final_layer.linear.register_forward_hook(lambda m, a, out: seen.update(linear=out.dtype))
    vb_terms = GaussianDiffusion.vb_terms_bpd

    def recording(self, output, x_start, x_t, t):
        result = vb_terms(self, output, x_start, x_t, t)
        seen["vb"] = {output.dtype, x_start.dtype, x_t.dtype, result.dtype}
        return result

    monkeypatch.setattr(GaussianDiffusion, "vb_terms_bpd", recording)
    fp32 = learner.TrainingLoss(model, None, torch.device("cpu"))(batch, t, noise)
    assert seen == {"linear": torch.float32, "vb": {torch.float32}}
    bf16 = learner.TrainingLoss(model, torch.bfloat16, torch.device("cpu"))(batch, t, noise)
    assert seen == {"linear": torch.bfloat16, "vb": {torch.float32}}
    for key in ("loss", "mse", "vb"):
        assert bf16[key].dtype == torch.float32 and torch.isfinite(bf16[key])
        # bf16 keeps 8 significant bits, a relative rounding of up to 2^-9 = 0.2% per operation, and the roundings
        # partly cancel in the means (3e-4 measured here); 1e-2 also allows for their accumulation through the layers
        assert float(bf16[key].detach()) == pytest.approx(float(fp32[key].detach()), rel=1e-2)
    bf16["loss"].backward()
    assert all(p.grad.dtype == torch.float32 and torch.isfinite(p.grad).all() for p in model.parameters())


def test_precision_errors(monkeypatch):
    assert learner.pick_precision("fp32", torch.device("cpu")) is None
    assert learner.pick_precision("bf16", torch.device("cpu")) == torch.bfloat16
    with pytest.raises(UsageError, match="--train.precision 'fp16': expected fp32 or bf16"):
        learner.pick_precision("fp16", torch.device("cpu"))
    monkeypatch.setattr(learner, "native_bf16", lambda device: False)
    with pytest.raises(UsageError, match="--train.precision bf16: cuda:0 has no native bfloat16 support") as err:
        learner.pick_precision("bf16", torch.device("cuda:0"))
    assert len(str(err.value).splitlines()) == 1
