"""Bad input, command by command: one line naming the option or file, exit code 2, before any work, nothing written.

Each case is one row of docs/reliability.md."""

from __future__ import annotations

import json
import shutil
import struct
import zipfile
from pathlib import Path

import numpy as np
import pytest
import torch

from tax3d.checkpoint import WEIGHT_FIELDS
from tax3d.cli import main
from tax3d.model.tax3d import Tax3D

from tests.conftest import one_line_error, synthetic_demo, tiny_model

ROOT = Path(__file__).resolve().parents[1]
SHIPPED = ROOT / "checkpoints" / "tax3d-cd-simple"



@pytest.fixture
def checkpoint(tmp_path):
    folder = tmp_path / "ckpt"
    tiny_model(task="hangproccloth-simple").save_pretrained(folder)
    return folder


def test_no_command_prints_usage_and_fails(capsys):
    assert main([]) == 2
    assert "usage: tax3d <command>" in capsys.readouterr().err
    assert main(["--help"]) == 0


@pytest.mark.parametrize("argv, expected", [
    (["train", "--preset", "cpu", "--train.lr", "-1"], "--train.lr -1.0: expected a positive number"),
    (["train", "--preset", "cpu", "--train.val-every", "0"], "--train.val-every 0"),
    (["train", "--preset", "cpu", "--train.ema", "1.5"], "--train.ema 1.5"),
    (["predict", "--checkpoint", "C", "--demos", "D", "--batch-scenes", "0"], "--batch-scenes 0"),
    (["eval", "--checkpoint", "C", "--replan-every", "-1"], "--replan-every -1"),
    (["eval", "--checkpoint", "C", "--first-index", "-5"], "--first-index -5"),
    (["eval", "--checkpoint", "C", "--max-points", "-1"], "--max-points -1"),
    (["eval", "--checkpoint", "C", "--policy-offset", "nan", "0", "0"], "--policy-offset nan 0.0 0.0"),
    (["generate", "--render-every", "0"], "--render-every 0"),
    (["generate", "--num", "0"], "--num 0"),
    (["cloud", "--depth", "d", "--mask", "m", "--intrinsics", "k", "--pose", "p", "--out", "c.npy",
      "--depth-scale", "0"], "--depth-scale 0.0: expected a positive number"),
])
def test_numbers_of_the_wrong_sign_or_kind(capsys, argv, expected):
    one_line_error(capsys, argv, expected)


@pytest.mark.parametrize("argv, expected", [
    (["train", "--preset", "cpu", "--model.hidden-size", "100", "--model.num-heads", "3"],
     "--model.hidden-size 100: expected a multiple of model.num_heads (3)"),
    (["train", "--preset", "cpu", "--diffusion.num-timesteps", "20", "--diffusion.sample-steps", "10"],
     "--diffusion.num-timesteps 20: expected at least 21"),
    (["train", "--preset", "cpu", "--diffusion.sample-steps", "200"],
     "--diffusion.sample-steps 200: expected at most diffusion.num_timesteps (100)"),
    (["generate", "--task", "hangproccloth-multimodal", "--first-index", "3"], "--first-index 3: "),
    (["generate", "--camera-out", "cams", "--camera.views"], "--camera.views: none given"),
])
def test_options_that_conflict_fail_as_one_option(capsys, argv, expected):
    """A check across options (a dataclass's conflicts()) names one option, in the words of the field checks."""
    one_line_error(capsys, argv, expected)


def test_outputs_that_cannot_be_written_fail_before_any_work(tmp_path, capsys, demos, checkpoint):
    a_file = tmp_path / "a_file"
    a_file.write_text("x")
    one_line_error(capsys, ["train", "--preset", "cpu", "--out", a_file, "--data.train", demos], "--out", "is a file")
    one_line_error(capsys, ["eval", "--checkpoint", checkpoint, "--out", a_file], "--out", "is a file")
    one_line_error(capsys, ["predict", "--checkpoint", checkpoint, "--demos", demos, "--out", a_file / "p.npz"],
                   "--out", "is a file")
    one_line_error(capsys, ["predict", "--checkpoint", checkpoint, "--demos", demos, "--summary", tmp_path],
                   "--summary", "is a folder")
    assert a_file.read_text() == "x"


def test_unwritable_folder(tmp_path, capsys, demos, checkpoint, monkeypatch):
    locked = tmp_path / "locked"
    locked.mkdir()
    real_access = __import__("os").access
    monkeypatch.setattr("tax3d.options.os.access", lambda p, mode: Path(p) != locked and real_access(p, mode))
    one_line_error(capsys, ["eval", "--checkpoint", checkpoint, "--out", locked / "eval"], "not writable")
    one_line_error(capsys, ["predict", "--checkpoint", checkpoint, "--demos", demos, "--out", locked / "p.npz"],
                   "not writable")
    assert not list(locked.iterdir())


def test_eval_data_given_a_split_folder(capsys, demos, checkpoint):
    one_line_error(capsys, ["eval", "--checkpoint", checkpoint, "--data", demos],
                   f"--data {demos}", "holds demo files itself")
    one_line_error(capsys, ["eval", "--checkpoint", checkpoint, "--data", demos.parent], "has none of the folders")


def test_huge_coordinates_are_a_bad_file(tmp_path, capsys, checkpoint):
    demo = synthetic_demo(0)
    demo["action_pc"] = demo["action_pc"] * 1e30
    demo["flow"] = demo["flow"] * 0
    folder = tmp_path / "huge"
    folder.mkdir()
    np.savez(folder / "demo_0.npz", **{k: (np.array(v, dtype=object) if isinstance(v, dict) else v)
                                       for k, v in demo.items()})
    one_line_error(capsys, ["predict", "--checkpoint", checkpoint, "--demos", folder], "demo_0.npz", "beyond")
    one_line_error(capsys, ["train", "--preset", "cpu", "--data.train", folder, "--out", tmp_path / "run"],
                   "demo_0.npz")
    assert not (tmp_path / "run").exists()


def test_non_finite_loss_stops_training_without_a_checkpoint(tmp_path, capsys, demos, monkeypatch):
    from tax3d.training import tax3d as train

    forward = train.TrainingLoss.forward

    def poisoned(self, batch, t, noise):
        losses = forward(self, batch, t, noise)
        return {**losses, "loss": losses["loss"] * float("nan")}

    monkeypatch.setattr(train.TrainingLoss, "forward", poisoned)
    out = tmp_path / "run"
    one_line_error(capsys, ["train", "--preset", "cpu", "--model.hidden_size", "16", "--model.depth", "1",
                            "--data.num_action_points", "16", "--data.num_anchor_points", "16",
                            "--train.num_workers", "0", "--data.train", demos, "--train.steps", "3",
                            "--train.val_every", "1", "--out", out], "training loss is nan at step 1")
    assert not (out / "last").exists() and not (out / "best").exists()


def test_checkpoint_without_its_diffusion_section(tmp_path, capsys, demos, checkpoint):
    config = json.loads((checkpoint / "config.json").read_text())
    del config["diffusion"]
    (checkpoint / "config.json").write_text(json.dumps(config))
    one_line_error(capsys, ["predict", "--checkpoint", checkpoint, "--demos", demos], "no 'diffusion' section")


@pytest.mark.parametrize("field", [f"{section}.{name}" for section, names in WEIGHT_FIELDS.items()
                                   for name in names])
def test_a_checkpoint_without_a_field_its_weights_need_is_refused(tmp_path, capsys, demos, checkpoint, field):
    """Without model.variant a CP checkpoint would be taken for CD, without diffusion.prediction an x_0 network for
    an epsilon one: each such field is required, named when missing."""
    section, name = field.split(".")
    config = json.loads((checkpoint / "config.json").read_text())
    del config[section][name]
    (checkpoint / "config.json").write_text(json.dumps(config))
    one_line_error(capsys, ["predict", "--checkpoint", checkpoint, "--demos", demos], f"no {field}; expected")
    with pytest.raises(ValueError, match=f"no {field};"):
        Tax3D.from_pretrained(checkpoint)


def test_weights_that_do_not_fit_the_config_are_named(tmp_path, capsys, demos, checkpoint):
    config = json.loads((checkpoint / "config.json").read_text())
    config["model"]["depth"] += 1
    (checkpoint / "config.json").write_text(json.dumps(config))
    one_line_error(capsys, ["predict", "--checkpoint", checkpoint, "--demos", demos],
                   "weights do not match config.json")


def test_damaged_weights_are_detected_by_their_hash(tmp_path, capsys, demos):
    folder = tmp_path / "shipped"
    shutil.copytree(SHIPPED, folder)
    data = bytearray((folder / "model.safetensors").read_bytes())
    data[-100] ^= 0xFF  # a byte inside a tensor: the file still parses
    (folder / "model.safetensors").write_bytes(bytes(data))
    one_line_error(capsys, ["predict", "--checkpoint", folder, "--demos", demos], "model.safetensors", "sha256")
    Tax3D.from_pretrained(SHIPPED)  # the shipped checkpoints record the hash of their weights, and match it


def test_config_values_of_the_wrong_type(tmp_path, capsys, demos, checkpoint):
    config = json.loads((checkpoint / "config.json").read_text())
    config["model"]["hidden_size"] = "64"
    (checkpoint / "config.json").write_text(json.dumps(config))
    one_line_error(capsys, ["predict", "--checkpoint", checkpoint, "--demos", demos],
                   "model.hidden_size is '64'; expected an integer")


def test_action_points_stored_as_strings(tmp_path, capsys, checkpoint):
    demo = synthetic_demo(0)
    folder = tmp_path / "strings"
    folder.mkdir()
    arrays = {k: (np.array(v, dtype=object) if isinstance(v, dict) else v) for k, v in demo.items()}
    arrays["action_pc"] = demo["action_pc"].astype(str)
    np.savez(folder / "demo_0.npz", **arrays)
    one_line_error(capsys, ["predict", "--checkpoint", checkpoint, "--demos", folder], "action_pc has dtype")


def test_broken_resume_files(tmp_path, capsys, demos):
    out = tmp_path / "run"
    args = ["train", "--preset", "cpu", "--model.hidden_size", "16", "--model.depth", "1",
            "--data.num_action_points", "16", "--data.num_anchor_points", "16", "--train.num_workers", "0",
            "--data.train", demos, "--train.steps", "2", "--train.val_every", "2", "--out", out]
    assert main(list(map(str, args))) == 0
    capsys.readouterr()
    state = out / "last" / "training_state.pt"
    good = state.read_bytes()
    state.write_bytes(good[: len(good) // 2])
    one_line_error(capsys, [*args, "--train.steps", "4", "--resume"], "training_state.pt", "unreadable")
    state.write_bytes(good)
    (out / "last" / "model.safetensors").write_bytes(b"garbage" * 10)
    one_line_error(capsys, [*args, "--train.steps", "4", "--resume"], "model.safetensors")


def npz_with_member(path: Path, name: str, payload: bytes, demo: dict) -> None:
    arrays = {k: (np.array(v, dtype=object) if isinstance(v, dict) else v) for k, v in demo.items() if k != name}
    np.savez(path, **arrays)
    with zipfile.ZipFile(path, "a") as zf:
        zf.writestr(name + ".npy", payload)


def test_hostile_npy_members(tmp_path, capsys, checkpoint):
    folder = tmp_path / "hostile"
    folder.mkdir()
    header = "{'descr': '<f8', 'fortran_order': False, 'shape': (100000000000, 3), }".ljust(117) + "\n"
    npy = b"\x93NUMPY\x01\x00" + struct.pack("<H", len(header)) + header.encode()
    npz_with_member(folder / "demo_0.npz", "action_pc", npy, synthetic_demo(0))
    one_line_error(capsys, ["predict", "--checkpoint", checkpoint, "--demos", folder], "demo_0.npz", "claims shape")

    # a pickled list nested 200,000 deep, written by hand (pickle.dumps itself would recurse)
    payload = b"\x80\x02" + b"]" * 200_000 + b"a" * 199_999 + b"."
    header = "{'descr': '|O', 'fortran_order': False, 'shape': (), }".ljust(117) + "\n"
    npy = b"\x93NUMPY\x01\x00" + struct.pack("<H", len(header)) + header.encode() + payload
    npz_with_member(folder / "demo_0.npz", "deform_params", npy, synthetic_demo(0))
    one_line_error(capsys, ["predict", "--checkpoint", checkpoint, "--demos", folder], "demo_0.npz")


def test_python_api_errors_speak_in_api_terms():
    model = tiny_model()
    action, anchor = synthetic_demo(0)["action_pc"], synthetic_demo(0)["anchor_pc"]
    with pytest.raises(ValueError, match="num_samples is -1"):
        model.predict(action, anchor, num_samples=-1)
    with pytest.raises(TypeError, match="steps is 2.5"):
        model.predict(action, anchor, steps=2.5)
    with pytest.raises(ValueError, match=r"^steps 500"):
        model.predict(action, anchor, steps=500)
    with pytest.raises(TypeError, match="action_points has dtype"):
        model.predict(action.astype(str), anchor)
    with pytest.raises(TypeError, match="anchor_points has dtype"):
        model.predict(action, anchor.astype(complex))
    with pytest.raises(TypeError, match="anchor_points has dtype"):
        model.predict(torch.as_tensor(action), torch.as_tensor(anchor, dtype=torch.complex64))
    with pytest.raises(ValueError, match="batch_scenes is 0"):
        model.predict_scenes([(action, anchor)], batch_scenes=0)


def test_the_package_front_door():
    import tax3d

    assert tax3d.Tax3D is Tax3D
    from tax3d import Tax3D as FrontDoor  # noqa: F401


def test_commands_are_quiet():
    """No pybullet banner on any command; --help prints help alone."""
    import subprocess
    import sys

    for argv in (["-c", "import tax3d.sim.env, tax3d.sim.generate"], ["-m", "tax3d.cli", "generate", "--help"]):
        done = subprocess.run([sys.executable, *argv], capture_output=True, text=True, timeout=120)
        assert done.returncode == 0 and "pybullet build time" not in done.stdout + done.stderr
    assert done.stdout.startswith("usage: tax3d generate") and done.stderr == ""


def test_generate_with_nothing_left_to_do_says_so(tmp_path, capsys, monkeypatch):
    from tax3d.cli import generate

    stats = {"episodes": 0, "successes": 0, "success_rate": float("nan"), "seconds_per_episode": float("nan"),
             "exploded": 0, "broken": 0, "written": 0, "skipped": 40, "failed": []}
    monkeypatch.setattr(generate, "generate", lambda args: stats)
    assert main(["generate", "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "nothing to generate: the 40 demos asked for are already in" in out and "nan" not in out
