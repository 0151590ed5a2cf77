"""`--device` options: auto, cpu, cuda, cuda:K; a one-line error, exit code 2, for what cannot run here."""

from pathlib import Path

import pytest
import torch

from tax3d.cli import main
from tax3d.devices import pick_device
from tax3d.errors import UsageError

CHECKPOINT = str(Path(__file__).resolve().parents[1] / "checkpoints" / "tax3d-cd-simple")


def test_pick_device():
    assert pick_device("cpu") == torch.device("cpu")
    assert pick_device("auto").type == ("cuda" if torch.cuda.is_available() else "cpu")
    for bad in ("tpu", "cuda:x", "gpu0"):
        with pytest.raises(UsageError, match="expected auto, cpu, cuda or cuda:K"):
            pick_device(bad, "--device")


@pytest.mark.skipif(torch.cuda.is_available(), reason="needs a machine without CUDA")
@pytest.mark.parametrize("command", ["predict", "eval"])
def test_cuda_without_a_gpu_is_a_one_line_error(command, capsys, tmp_path):
    args = {"predict": ["predict", "--checkpoint", CHECKPOINT, "--demos", str(tmp_path)],
            "eval": ["eval", "--checkpoint", CHECKPOINT, "--episodes", "1"]}[command]
    assert main(args + ["--device", "cuda"]) == 2
    err = capsys.readouterr().err.strip()
    assert "--device cuda: no CUDA device is available" in err and len(err.splitlines()) == 1
