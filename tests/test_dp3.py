"""The DP3 baseline: scheduler maths, normaliser, UNet, dataset windows, training, checkpoints, a real rollout."""

from __future__ import annotations

import functools
import json
import math

import numpy as np
import pytest
import torch

from tax3d.baselines.dp3 import DP3, is_dp3_checkpoint
from tax3d.policies.dp3 import DP3Policy
from tax3d.baselines.dp3 import config as cfg
from tax3d.baselines.dp3.dataset import TrajectoryDataset, rotate_batch
from tax3d.baselines.dp3.network import ConditionalUnet1D
from tax3d.checkpoint import read_log as read_train_log
from tax3d.baselines.dp3.normalizer import MinMaxNormalizer
from tax3d.baselines.dp3.scheduler import DDIM, squaredcos_cap_v2_betas
from tax3d.cli import main
from tax3d.data.format import save_demo
from tax3d.errors import UsageError
from tax3d.training.budget import timing_step
from tax3d.sim.cloth import SIMPLE_CLOTH

from tests.conftest import one_line_error

T, N_CLOTH, N_ANCHOR = 10, 24, 20  # steps and stored points of the synthetic demos


def tiny_config(**data) -> cfg.DP3Config:
    return cfg.DP3Config(
        model=cfg.ModelConfig(point_dims=(16, 32), encoder_dim=16, state_dims=(16, 16), down_dims=(16, 32),
                              step_embed_dim=16),
        data=cfg.DataConfig(num_action_points=16, num_anchor_points=16, **data),
        train=cfg.TrainConfig(lr=1e-3, weight_decay=1e-6, warmup_steps=2, batch_size=8, steps=4, save_every=2,
                              threads=1),
    )


def synthetic_demo(seed: int, steps: int = T) -> dict:
    """A demo whose trajectory encodes the step: gripper x and every target coordinate equal t."""
    rng = np.random.default_rng(seed)
    t = np.arange(steps, dtype=np.float32)
    cloth = rng.normal(size=(N_CLOTH, 3)) + [0.0, 5.0, 8.0]
    anchor = rng.normal(size=(N_ANCHOR, 3)) + [4.0, -6.0, 3.0]
    pos = np.zeros((steps, 2, 3), np.float32) + [[0.0, 5.0, 8.0], [1.0, 5.0, 8.0]]
    pos[:, :, 0] += t[:, None]
    return {
        "action_pc": cloth, "action_seg": np.ones(N_CLOTH), "anchor_pc": anchor,
        "anchor_seg": np.zeros(N_ANCHOR, dtype=np.int32), "flow": np.zeros((N_CLOTH, 3)),
        "speed_factor": np.array(1.0), "rot": np.zeros(3), "trans": np.zeros(3), "deform_params": dict(SIMPLE_CLOTH),
        "anchors": {0: {"pos": np.zeros(3), "vertices": [0]}},
        "traj_gripper_pos": pos, "traj_gripper_vel": np.full((steps, 2, 3), 0.5, np.float32),
        "traj_targets": np.broadcast_to(t[:, None, None], (steps, 2, 3)).astype(np.float32),
        "traj_action_pc": (cloth[None] + t[:, None, None] * [0.1, 0.0, 0.0]).astype(np.float32),
        "traj_action_idx": np.arange(N_CLOTH), "traj_anchor_pc": anchor.astype(np.float32),
    }


@pytest.fixture(autouse=True)
def one_thread():
    """One torch thread (what the rollouts use); the training command's --threads must not leak to other tests."""
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(threads)


@pytest.fixture
def demos(tmp_path):
    folder = tmp_path / "demos"
    folder.mkdir()
    for i in range(2):
        save_demo(folder / f"demo_{i}.npz", synthetic_demo(i))
    return folder


def fitted_model(config=None, seed=0) -> DP3:
    torch.manual_seed(seed)
    model = DP3(config or tiny_config())
    rng = torch.Generator().manual_seed(seed)
    model.fit_normalizers(torch.randn(100, 3, generator=rng) * 3, torch.randn(50, 12, generator=rng),
                          torch.randn(50, 6, generator=rng))
    return model.eval()


def observation(model: DP3, seed=0):
    rng = torch.Generator().manual_seed(seed)
    n = model.config.data.num_action_points + model.config.data.num_anchor_points
    return torch.randn(2, 2, n, 3, generator=rng), torch.randn(2, 2, 12, generator=rng)


# --- scheduler -------------------------------------------------------------------------------------------------


def test_squaredcos_betas():
    betas = squaredcos_cap_v2_betas(100)
    assert betas.shape == (100,) and bool((betas > 0).all() and (betas <= 0.999).all())
    assert betas[-1] == pytest.approx(0.999)  # the cap binds at the end of the cosine schedule
    abar = lambda s: math.cos((s + 0.008) / 1.008 * math.pi / 2) ** 2
    assert float(torch.cumprod(1 - betas, 0)[49]) == pytest.approx(abar(0.5) / abar(0.0), rel=1e-9)


def test_ddim_with_the_true_x0_follows_the_forward_process_and_ends_at_x0():
    ddim = DDIM(100, 10)
    assert ddim.timesteps() == [90, 80, 70, 60, 50, 40, 30, 20, 10, 0]
    x0 = torch.rand(3, 4, 6, dtype=torch.float64) * 2 - 1
    eps = torch.randn(3, 4, 6, dtype=torch.float64)
    x = ddim.add_noise(x0, eps, torch.full((3,), 90))
    for t in ddim.timesteps():
        assert torch.allclose(x, ddim.add_noise(x0, eps, torch.full((3,), t)), atol=1e-9)  # deterministic path
        x = ddim.step(x0, t, x)
    assert torch.allclose(x, x0, atol=1e-12)  # alpha_bar = 1 after the last step
    sampled = ddim.sample(lambda x, t: x0.float(), (3, 4, 6), torch.Generator().manual_seed(0))
    assert torch.allclose(sampled, x0.float(), atol=1e-6)


def test_ddim_matches_the_diffusers_oracle():
    diffusers = pytest.importorskip("diffusers")
    oracle = diffusers.DDIMScheduler(num_train_timesteps=100, beta_schedule="squaredcos_cap_v2", clip_sample=True,
                                     set_alpha_to_one=True, steps_offset=0, prediction_type="sample")
    oracle.set_timesteps(10)
    ddim = DDIM(100, 10)
    assert oracle.timesteps.tolist() == ddim.timesteps()
    assert torch.allclose(oracle.betas.double(), ddim.betas, atol=1e-6)
    x, out = torch.randn(2, 4, 6), torch.randn(2, 4, 6) * 2  # outputs beyond [-1, 1]: clipping matters
    for t in (90, 40, 0):
        assert torch.allclose(oracle.step(out, t, x).prev_sample, ddim.step(out, t, x), atol=1e-5)


# --- normaliser, network -----------------------------------------------------------------------------------------


def test_normaliser_round_trip_constant_dimension_and_rotation():
    data = torch.randn(200, 6) * torch.tensor([1.0, 2.0, 3.0, 0.5, 0.1, 0.0]) + 4.0
    norm = MinMaxNormalizer(6).fit(data)
    y = norm.normalize(data)
    assert torch.allclose(norm.unnormalize(y), data, atol=1e-5)
    assert y[:, :5].min() == pytest.approx(-1, abs=1e-5) and y[:, :5].max() == pytest.approx(1, abs=1e-5)
    assert torch.allclose(y[:, 5], torch.zeros(200))  # a constant dimension maps to 0
    turned = rotate_batch({"x": data[None]}, torch.tensor([2.0]))["x"][0]
    assert MinMaxNormalizer(6).fit(data, rotation_invariant=True).normalize(turned).abs().max() <= 1 + 1e-5


def test_unet_shape_and_film_conditioning():
    torch.manual_seed(0)
    unet = ConditionalUnet1D(6, 32, down_dims=(16, 32, 64), step_embed_dim=16)
    x, t, cond = torch.randn(3, 4, 6), torch.tensor([0, 50, 99]), torch.randn(3, 32)
    out = unet(x, t, cond)
    assert out.shape == (3, 4, 6)
    assert not torch.allclose(out, unet(x, t, cond + 1.0))  # the observation condition changes the output
    assert not torch.allclose(out, unet(x, t + 1, cond))  # and so does the diffusion step
    with pytest.raises(UsageError, match="multiple of 4"):
        DP3(cfg.DP3Config(model=cfg.ModelConfig(horizon=6)))


# --- dataset -----------------------------------------------------------------------------------------------------


def test_dataset_windows_and_padding(demos):
    data = TrajectoryDataset(demos, horizon=4, n_obs_steps=2, num_action_points=16, num_anchor_points=16)
    assert len(data) == 2 * T  # one sample per step of each episode
    first, last = data[0], data[T - 1]
    assert first["points"].shape == (2, 32, 3) and first["state"].shape == (2, 12) and first["action"].shape == (4, 6)
    assert first["state"][:, 0].tolist() == [0.0, 0.0]  # the first observation repeated before the episode
    assert first["action"][:, 0].tolist() == [0.0, 1.0, 2.0, 3.0]  # actions from the current step on
    assert data[5]["state"][:, 0].tolist() == [4.0, 5.0] and data[5]["action"][:, 0].tolist() == [5, 6, 7, 8]
    assert last["action"][:, 0].tolist() == [T - 1] * 4  # the last action repeated after the episode
    demo = synthetic_demo(0)
    assert torch.allclose(first["points"][0, 16:], torch.as_tensor(demo["traj_anchor_pc"][:16]))
    assert torch.allclose(data[5]["points"][1, :16], torch.as_tensor(demo["traj_action_pc"][5, :16]))
    assert torch.equal(data[T]["action"][:, 0], first["action"][:, 0])  # the second episode starts over


def test_rotation_turns_points_state_and_actions_together(demos):
    data = TrajectoryDataset(demos, num_action_points=16, num_anchor_points=16)
    batch = {k: torch.stack([data[i][k] for i in (0, 7)]) for k in data[0]}
    turned = rotate_batch(batch, torch.tensor([0.0, math.pi / 2]))
    assert torch.allclose(turned["action"][0], batch["action"][0])
    gripper, target = batch["state"][1, -1, :3], batch["action"][1, 0, :3]
    new_gripper, new_target = turned["state"][1, -1, :3], turned["action"][1, 0, :3]
    assert torch.allclose(new_gripper, torch.stack([-gripper[1], gripper[0], gripper[2]]), atol=1e-5)
    assert torch.allclose((new_target - new_gripper).norm(), (target - gripper).norm(), atol=1e-5)


# --- training and checkpoints ------------------------------------------------------------------------------------


def test_a_few_steps_reduce_the_loss():
    model = fitted_model()
    points, state = observation(model)
    batch = {"points": points, "state": state, "action": torch.randn(2, 4, 6)}
    optimizer = torch.optim.AdamW(model.parameters(), lr=3e-3)
    rng = torch.Generator().manual_seed(0)
    fixed = dict(t=torch.randint(100, (2,), generator=rng), noise=torch.randn(2, 4, 6, generator=rng))
    first = float(model.loss(batch, **fixed).detach())
    model.train()
    for _ in range(40):
        loss = model.loss(batch, **fixed)
        optimizer.zero_grad()
        loss.backward()
        optimizer.step()
    assert float(model.loss(batch, **fixed).detach()) < 0.5 * first


def test_save_load_round_trip_gives_identical_actions(tmp_path):
    model = fitted_model()
    model.save_pretrained(tmp_path / "ckpt")
    assert is_dp3_checkpoint(tmp_path / "ckpt")
    loaded = DP3.from_pretrained(tmp_path / "ckpt")
    points, state = observation(model)
    a = model.predict_action(points, state, torch.Generator().manual_seed(3))
    b = loaded.predict_action(points, state, torch.Generator().manual_seed(3))
    assert a.shape == (2, 4, 6) and torch.equal(a, b)
    assert torch.equal(loaded.normalizers["action"].high, model.normalizers["action"].high)


def read_log(out):
    return read_train_log(out / "log.jsonl")


def test_train_command_writes_a_checkpoint_and_resumes_exactly(tmp_path, demos, monkeypatch):
    monkeypatch.setitem(cfg.PRESETS, "cpu", tiny_config)
    common = ["train-dp3", "--data.train", str(demos), "--preset", "cpu", "--device", "cpu",
              "--data.task", "hangproccloth-simple"]
    assert main([*common, "--out", str(tmp_path / "whole"), "--train.steps", "4"]) == 0
    assert main([*common, "--out", str(tmp_path / "split"), "--train.steps", "2"]) == 0
    assert main([*common, "--out", str(tmp_path / "split"), "--train.steps", "4", "--resume"]) == 0  # from step 2
    whole, split = read_log(tmp_path / "whole"), read_log(tmp_path / "split")
    assert [r["step"] for r in split] == [1, 2, 3, 4] and all(math.isfinite(r["loss"]) for r in whole)
    assert [r["loss"] for r in split] == pytest.approx([r["loss"] for r in whole], rel=1e-5)
    model = DP3.from_pretrained(tmp_path / "whole" / "last")
    assert model.config.data.task == "hangproccloth-simple" and model.config.model.variant == "dp3"
    assert (tmp_path / "whole" / "last" / "training_state.pt").is_file()
    assert json.loads((tmp_path / "whole" / "config.json").read_text())["kind"] == "dp3"
    resumed = DP3.from_pretrained(tmp_path / "split" / "last")
    for (name, a), b in zip(model.state_dict().items(), resumed.state_dict().values()):
        assert torch.allclose(a, b, atol=1e-6), name


def test_one_run_one_folder(tmp_path, demos, monkeypatch, capsys):
    """A second run into a folder whose lock is held is refused; a rerun with other options or demos is refused,
    naming what differs, and trains nothing; --fresh starts afresh."""
    from tax3d.training import runlock

    monkeypatch.setitem(cfg.PRESETS, "cpu", tiny_config)
    out = tmp_path / "run"
    common = ["train-dp3", "--data.train", str(demos), "--preset", "cpu", "--device", "cpu", "--data.task",
              "hangproccloth-simple", "--out", str(out), "--train.steps", "2"]
    with runlock.hold(out):
        assert "another run" in one_line_error(capsys, common) and not (out / "log.jsonl").exists()
    assert main(common) == 0
    capsys.readouterr()
    before = (out / "log.jsonl").read_text()
    err = one_line_error(capsys, [*common, "--train.lr", "0.5"])
    assert "holds another run: --train.lr" in err and (out / "log.jsonl").read_text() == before
    save_demo(demos / "demo_0.npz", synthetic_demo(5))
    err = one_line_error(capsys, common)
    assert "--data.train: these demonstrations differ" in err
    assert main([*common, "--train.lr", "0.5", "--fresh"]) == 0
    assert [r["step"] for r in read_log(out)] == [1, 2] and json.loads((out / "config.json").read_text())["train"]["lr"] == 0.5


def test_a_minutes_plan_fixes_the_steps_from_the_measured_rate(tmp_path, demos, monkeypatch, capsys):
    """--train.minutes M: the first steps are timed and train.steps becomes what fits in M minutes (DP3 gets the
    wall time of the table's TAX3D rows), recorded in config.json; the run ends at that step."""
    import time

    clock = iter(range(10_000))
    monkeypatch.setattr(time, "time", lambda: float(next(clock)))  # each call one second later
    monkeypatch.setitem(cfg.PRESETS, "cpu", lambda: tiny_config())
    out = tmp_path / "run"
    assert main(["train-dp3", "--data.train", str(demos), "--preset", "cpu", "--device", "cpu", "--data.task",
                 "hangproccloth-simple", "--train.minutes", "2", "--out", str(out)]) == 0
    steps = json.loads((out / "config.json").read_text())["train"]["steps"]
    assert timing_step(tiny_config().train.warmup_steps) < steps < 120
    assert [r["step"] for r in read_log(out)][-1] == steps
    assert f"planned {steps} steps for 2 minutes" in capsys.readouterr().err


def test_a_planned_run_killed_and_resumed_ends_at_its_plan(tmp_path, demos, monkeypatch):
    """last/ records the planned steps (not the preset's): a run killed after its plan resumes and trains on to the
    plan's last step."""
    import time

    from tax3d.training import batches

    clock = iter(range(100_000))
    monkeypatch.setattr(time, "time", lambda: float(next(clock)))
    monkeypatch.setitem(cfg.PRESETS, "cpu", lambda: tiny_config())
    batch = batches.dp3_batch

    def dying(dataset, config, step, device):
        if step == 21:
            raise KeyboardInterrupt
        return batch(dataset, config, step, device)

    args = ["train-dp3", "--data.train", str(demos), "--preset", "cpu", "--device", "cpu", "--data.task",
            "hangproccloth-simple", "--train.minutes", "2", "--out", str(tmp_path / "run")]
    monkeypatch.setattr(batches, "dp3_batch", dying)
    assert main(args) == 130
    saved = json.loads((tmp_path / "run" / "last" / "config.json").read_text())["train"]["steps"]
    assert saved > 21 and saved == json.loads((tmp_path / "run" / "config.json").read_text())["train"]["steps"]
    monkeypatch.setattr(batches, "dp3_batch", batch)
    assert main(args) == 0
    steps = json.loads((tmp_path / "run" / "config.json").read_text())["train"]["steps"]
    assert read_log(tmp_path / "run")[-1]["step"] == steps > 21


def test_a_minutes_plan_is_timed_again_at_every_save(tmp_path, demos, monkeypatch, capsys):
    """Steps that slow down after the plan was made shorten the run at the next save of last/, as a `tax3d train`
    plan is re-timed at its validations: the steps are recorded in config.json and the log line `replan`, the run
    ends at them, near its minutes, and the learning rate still decays to the end."""
    import itertools
    import time

    calls = itertools.count()

    def clock() -> float:  # one second a call, then three: the steps after the plan take three times as long
        n = next(calls)
        return float(n if n < 40 else 40 + 3 * (n - 40))

    monkeypatch.setattr(time, "time", clock)
    monkeypatch.setitem(cfg.PRESETS, "cpu", lambda: tiny_config())
    out = tmp_path / "run"
    assert main(["train-dp3", "--data.train", str(demos), "--preset", "cpu", "--device", "cpu", "--data.task",
                 "hangproccloth-simple", "--train.minutes", "4", "--out", str(out)]) == 0
    log = read_log(out)
    planned = next(r["plan"]["steps"] for r in log if "plan" in r)
    replans = [r["replan"] for r in log if "replan" in r]
    steps = json.loads((out / "config.json").read_text())["train"]["steps"]
    assert replans and replans[0]["steps"] < planned and replans[-1]["steps"] == steps == log[-1]["step"]
    assert log[-1]["seconds"] == pytest.approx(240, abs=15)
    lrs = [r["lr"] for r in log]
    assert lrs[-1] < 0.05 * max(lrs) and all(b <= a for a, b in zip(lrs[20:], lrs[21:]))
    assert "re-planned" in capsys.readouterr().err


def test_bad_inputs(tmp_path, capsys):
    with pytest.raises(UsageError, match="no such checkpoint"):
        DP3.from_pretrained(tmp_path / "nope")
    fitted_model().save_pretrained(tmp_path / "ckpt")
    (tmp_path / "ckpt" / "model.safetensors").unlink()
    err = one_line_error(capsys, ["eval", "--checkpoint", str(tmp_path / "ckpt"), "--out", str(tmp_path / "e")])
    assert "incomplete checkpoint, model.safetensors is missing" in err
    plain = tmp_path / "plain"
    plain.mkdir()
    demo = {k: v for k, v in synthetic_demo(0).items() if not k.startswith("traj_")}
    save_demo(plain / "demo_0.npz", demo)
    dp3 = ["train-dp3", "--preset", "cpu"]
    err = one_line_error(capsys, [*dp3, "--data.train", str(plain), "--out", str(tmp_path / "run")])
    assert "demo_0.npz: no traj_gripper_pos" in err and "--trajectories" in err
    err = one_line_error(capsys, [*dp3, "--data.train", str(tmp_path / "missing"), "--out", str(tmp_path / "run")])
    assert "no such demonstration folder" in err
    err = one_line_error(capsys, [*dp3, "--data.train", str(plain), "--device", "tpu", "--out", str(tmp_path / "r")])
    assert "--device 'tpu'" in err


# --- a real rollout ----------------------------------------------------------------------------------------------


def test_policy_acts_in_a_real_rollout_and_through_eval(tmp_path, monkeypatch):
    from tax3d.cli import eval as ev
    from tax3d.sim import episode as sim_episode
    from tax3d.sim.scenes import process_env

    env = process_env(True, "cloth")
    grippers = env.reset(SIMPLE_CLOTH, 0.0, [0.0, 0.0, 0.0]).grippers
    model = fitted_model(tiny_config(task="hangproccloth-simple"))
    # An untrained network's actions fall inside the action limits: keep them near the grippers' start.
    model.normalizers["action"].fit(torch.as_tensor(np.stack([grippers - 0.05, grippers + 0.05])).reshape(2, 6))
    model.save_pretrained(tmp_path / "ckpt")

    seen = []

    class Recording(DP3Policy):
        def targets(self, cloth):
            seen.append(super().targets(cloth))
            return seen[-1]

    policy = Recording.from_pretrained(tmp_path / "ckpt", seed=1)
    ep = sim_episode.run_episode(env, SIMPLE_CLOTH, 0.0, [0.0, 0.0, 0.0], policy, steps=8)
    assert not ep.exploded and ep.released_pc is not None and isinstance(ep.success, bool)
    assert len(seen) == 8 and all(t.shape == (2, 3) and np.isfinite(t).all() for t in seen)
    assert policy.predictions == 2  # one action window per n_action_steps = 4 steps
    assert np.abs(np.stack(seen) - grippers).max() <= 0.05 + 1e-6

    monkeypatch.setattr(sim_episode, "run_episode", functools.partial(sim_episode.run_episode, steps=8))
    out = ev.evaluate(ev.Args(checkpoint=tmp_path / "ckpt", splits="unseen", episodes=1, workers=1, report=False,
                              out=tmp_path / "eval"), progress=False)
    (result,) = out["results"]
    assert not result.get("error") and result["rmse"] is None and result["predict_seconds"] > 0
    assert out["summary"]["variant"] == "dp3" and out["summary"]["splits"]["unseen"]["episodes"] == 1
