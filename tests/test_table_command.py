"""tax3d table end to end at a tiny budget: each row trains, is chosen on val, scored once on the test episodes;
a stop between rows loses nothing and a rerun scores nothing twice unless asked."""

import json
import shutil

import pytest

from tax3d.cli import train
from tax3d.eval import ledger
from tax3d.checkpoint import sha256
from tax3d.errors import UsageError
from tax3d.cli.table import Args, demos_digest, run
from tests.conftest import one_line_error


@pytest.fixture
def data(generated, tmp_path):
    demos, _ = generated
    root = tmp_path / "data"
    for split, name in (("train", "demo_0"), ("val", "demo_0"), ("unseen", "demo_100"), ("ood", "demo_100")):
        (root / split).mkdir(parents=True)
        shutil.copy(demos / "demo_0.npz", root / split / f"{name}.npz")
    return root


@pytest.fixture
def no_simulator(monkeypatch):
    """Episodes scored without the simulator, for the tests of the table's bookkeeping (which rows train, score and
    count): each episode a success whose goal is the demo's own. The simulated episodes of `tax3d eval` have tests
    of their own (tests/test_evaluate.py), and the README's block runs this command whole."""
    from tax3d.eval import runner

    def episode(job):
        result = {**runner.failed(job, ""), "success": True}
        del result["error"]
        return result

    monkeypatch.setattr(runner, "episode", episode)


@pytest.mark.usefixtures("no_simulator")
def test_rows_are_scored_once_and_a_stop_between_rows_resumes(data, tmp_path, capsys, monkeypatch, own_ledger):
    args = Args(task="hangproccloth-simple", variants="cd,cp", out=tmp_path / "bench", steps=2, episodes=1,
                num_train=1, num_val=1, workers=1, data=data, keep=tmp_path / "keep")
    real_train = train.run

    def stop_at_cp(train_args):
        if "/cp/" in train_args.out:
            raise KeyboardInterrupt
        return real_train(train_args)

    monkeypatch.setattr(train, "run", stop_at_cp)
    with pytest.raises(KeyboardInterrupt):
        run(args)
    row = json.loads((tmp_path / "keep" / "cd.json").read_text())  # the first row is kept before the stop
    assert row["kind"] == "table-row" and row["task"] == "hangproccloth-simple" and row["test"]["scorings"] == 1
    assert row["weights_sha256"] == sha256(tmp_path / "bench" / "cd" / "train" / row["weights"] / "model.safetensors")
    assert row["config"]["data"]["val"] == [str(data / "val")] and row["weights_chosen_on"] == "val"
    assert row["preset"] == "cpu" and set(row["splits"]) == {"unseen", "ood"}
    assert row["test"]["first_index"] == 100 and row["splits"]["unseen"]["episodes"] == 1
    assert row["data_sha256"]["unseen"] == demos_digest([data / "unseen" / "demo_100.npz"])  # which episodes
    assert row["data_sha256"]["train"] == demos_digest([data / "train" / "demo_0.npz"]) != row["data_sha256"]["ood"]
    low, high = row["splits"]["unseen"]["success_ci95"]
    assert low <= row["splits"]["unseen"]["success_rate"] <= high
    episodes = json.loads((tmp_path / "bench" / "cd" / "eval" / "results.json").read_text())["episodes"]
    assert [e["name"] for e in episodes] == ["demo_100", "demo_100"]  # the test episodes, not demo_0
    capsys.readouterr()

    monkeypatch.setattr(train, "run", real_train)
    assert run(args) == 0
    out = capsys.readouterr().out
    assert "training cd" not in out and "scoring cd" not in out  # kept: neither trained nor scored again
    assert "training cp" in out and "scoring cp" in out
    assert json.loads((tmp_path / "keep" / "cp.json").read_text())["test"]["scorings"] == 1

    assert run(args) == 0
    assert "scoring" not in capsys.readouterr().out
    args.variants, args.rescore = "cd", True
    assert run(args) == 0  # asked for: scored again, and the summary says how often
    assert json.loads((tmp_path / "keep" / "cd.json").read_text())["test"]["scorings"] == 2
    lines = ledger.read(own_ledger)  # every scoring, in the order made, each before its row was written
    assert [x["row"] for x in lines] == ["cd", "cp", "cd"] and lines[0]["weights_sha256"] == row["weights_sha256"]
    assert lines[0]["data_sha256"] == row["data_sha256"] and lines[0]["episodes"] == {"unseen": 1, "ood": 1}
    assert lines[0]["successes"] == ledger.successes(row["splits"]) and lines[0]["num_train"] == 1


@pytest.mark.usefixtures("no_simulator")
def test_a_row_deleted_and_kept_again_is_scored_twice_in_the_ledger(data, tmp_path, own_ledger):
    args = Args(task="hangproccloth-simple", variants="cd", out=tmp_path / "bench", steps=2, episodes=1,
                num_train=1, num_val=1, workers=1, data=data, keep=tmp_path / "keep")
    assert run(args) == 0
    first = json.loads((tmp_path / "keep" / "cd.json").read_text())
    shutil.rmtree(tmp_path / "bench")
    (tmp_path / "keep" / "cd.json").unlink()  # the row withdrawn: its scoring stays in the ledger
    assert run(args) == 0
    second = json.loads((tmp_path / "keep" / "cd.json").read_text())
    assert second["test"]["scorings"] == 1  # the row's own count starts again; the ledger's does not
    lines = ledger.of_row(ledger.read(own_ledger), "hangproccloth-simple", 1, "cd")
    assert [ledger.is_kept_row(x, r) for x, r in zip(lines, (first, second))] == [True, True]


@pytest.mark.usefixtures("no_simulator")
def test_a_row_trained_again_after_a_fix_counts_its_trainings_and_scorings(data, tmp_path, capsys, monkeypatch):
    """--retrain sets the scored weights aside and trains from the start; stopped before its scoring, a plain rerun
    is refused and the --retrain rerun scores the new weights (not a third training), and the summary counts two
    trainings and two scorings. A row
    scored in OUT whose copy in --keep was lost gets it back on a plain rerun."""
    from tax3d.cli import table

    args = Args(task="hangproccloth-simple", variants="cd", out=tmp_path / "bench", steps=2, episodes=1,
                num_train=1, num_val=1, workers=1, data=data, keep=tmp_path / "keep")
    assert run(args) == 0
    first = json.loads((tmp_path / "keep" / "cd.json").read_text())
    assert first["trainings"] == 1 and first["test"]["scorings"] == 1
    score = table._score

    def stopped(*a):
        raise KeyboardInterrupt

    monkeypatch.setattr(table, "_score", stopped)
    args.retrain, args.steps = True, 3
    with pytest.raises(KeyboardInterrupt):
        run(args)
    aside = tmp_path / "bench" / "cd" / "train.replaced-1"
    assert sha256(aside / first["weights"] / "model.safetensors") == first["weights_sha256"]
    assert (tmp_path / "bench" / "cd" / "train" / "DONE").is_file()
    monkeypatch.setattr(table, "_score", score)
    args.retrain = False  # a plain rerun would report the old row for the new weights: refused
    with pytest.raises(UsageError, match="--variants cd: .* begun by --retrain and not yet scored"):
        run(args)
    args.retrain = True
    capsys.readouterr()
    assert run(args) == 0
    assert "training cd" not in capsys.readouterr().out and not (tmp_path / "bench" / "cd" / "train.replaced-2").exists()
    second = json.loads((tmp_path / "keep" / "cd.json").read_text())
    assert second["trainings"] == 2 and second["test"]["scorings"] == 2
    assert second["weights_sha256"] != first["weights_sha256"] and second["validations"][-1]["step"] == 3

    (tmp_path / "keep" / "cd.json").unlink()
    args.retrain = False
    assert run(args) == 0 and "scoring" not in capsys.readouterr().out
    assert json.loads((tmp_path / "keep" / "cd.json").read_text()) == second


def test_the_earlier_name_of_the_command_says_its_name_today(capsys):
    one_line_error(capsys, ["benchmark", "--task", "hangbag"], "`tax3d benchmark` is renamed",
                   "use `tax3d table` with the same options")


def test_one_budget_and_the_multimodal_recipe(tmp_path, capsys):
    from tax3d.cli.table import preset_of
    from tax3d.cli import main

    assert main(["table", "--steps", "5", "--minutes", "3", "--out", str(tmp_path / "b")]) == 2
    assert "--steps 5: not with --minutes 3" in capsys.readouterr().err
    assert preset_of(Args(task="hangproccloth-multimodal")) == "cpu-multimodal"
    assert preset_of(Args(task="hangbag")) == "cpu" and preset_of(Args(task="hangbag", preset="paper")) == "paper"


def test_the_dp3_row_trains_on_the_same_demonstrations_with_trajectories(tmp_path, monkeypatch):
    """A dp3 row makes the train demos with their trajectories first (same split, same indices); the train demos of
    the other rows are those files without the trajectories, not a second simulation. DP3 trains on them for the
    table's minutes."""
    import numpy as np

    from tax3d.cli import table
    from tax3d.data import load_demo, write_demo
    from tax3d.sim import generate as gen

    calls, rng = [], np.random.default_rng(0)

    def fake_generate(a, progress=True):
        calls.append(a)
        for i in range(a.first_index, a.first_index + a.num) if a.trajectories else ():
            write_demo(a.out / f"demo_{i}.npz", rng.normal(size=(5, 3)), rng.normal(size=(4, 3)),
                       flow=rng.normal(size=(5, 3)), traj_targets=rng.normal(size=(3, 2, 3)))
        return {"failed": []}

    monkeypatch.setattr(gen, "generate", fake_generate)
    args = Args(task="hangproccloth-unimodal", variants="cd,dp3", out=tmp_path, num_train=8, minutes=30)
    assert table._check(args) == ["cd", "dp3"]
    kept = write_demo(tmp_path / "data" / "train" / "demo_0.npz", np.zeros((5, 3)), np.ones((4, 3)), flow=np.zeros((5, 3)))
    table._generate_data(args)
    plan = [(c.split, c.out.name, c.first_index, c.num, c.trajectories) for c in calls]
    assert plan == [("train", "train-traj", 0, 8, True), ("train", "train", 0, 8, False), ("val", "val", 0, 40, False),
                    ("unseen", "unseen", 100, 40, False), ("ood", "ood", 100, 40, False)]
    assert {c.max_attempts for c in calls} == {table.DATA_ATTEMPTS}
    for i in range(1, 8):
        with_traj, train = (load_demo(tmp_path / "data" / f / f"demo_{i}.npz") for f in ("train-traj", "train"))
        assert "traj_targets" in with_traj and not any(k.startswith("traj_") for k in train)
        assert all(np.array_equal(train[k], with_traj[k]) for k in ("action_pc", "anchor_pc", "flow"))
    assert not load_demo(kept)["action_pc"].any()  # a train demo already there is left as it is
    trained = []
    from tax3d.cli import train_dp3 as dp3_train

    def fake_run(a):
        trained.append(a)
        (tmp_path / "dp3" / "train").mkdir(parents=True)
        return 0

    monkeypatch.setattr(dp3_train, "run", fake_run)
    assert table._train(args, "dp3", tmp_path / "data").name == "last"
    assert trained[0].train.minutes == 30 and trained[0].data.task == "hangproccloth-unimodal"


def test_data_only_makes_the_rows_demonstrations_and_nothing_else(tmp_path, monkeypatch):
    from tax3d.cli import eval as evaluate

    calls = []
    monkeypatch.setattr("tax3d.sim.generate.generate", lambda a, progress=True: calls.append(a) or {"failed": []})
    monkeypatch.setattr(train, "run", lambda a: pytest.fail("--data-only trains nothing"))
    monkeypatch.setattr(evaluate, "evaluate", lambda a, progress=True, record=True: pytest.fail("--data-only scores nothing"))
    args = Args(task="hangbag", variants="dp3", out=tmp_path / "b", num_train=16, workers=2, data_only=True)
    assert run(args) == 0
    assert [(c.out.name, c.num, c.workers) for c in calls] == [
        ("train-traj", 16, 2), ("train", 16, 2), ("val", 40, 2), ("unseen", 40, 2), ("ood", 40, 2)]
    assert not (tmp_path / "b" / "dp3").exists() and not (tmp_path / "b" / "results.md").exists()


def test_a_row_records_the_table_command():
    from tax3d import provenance
    from tax3d.cli import table

    provenance.running(["table", "--task", "hangbag", "--keep", "docs/a b"])
    try:
        assert table.command() == "tax3d table --task hangbag --keep 'docs/a b'"
    finally:
        provenance.running(None)


def test_the_floor_and_ceiling_rows_score_fixed_goals_without_training(tmp_path, monkeypatch):
    from tax3d.cli import eval as evaluate

    asked = []

    def fake_evaluate(a, progress=True, record=True):
        asked.append(a)
        a.out.mkdir(parents=True)  # as evaluate does
        split = {"episodes": 1, "success_rate": 1.0, "success_ci95": [0.2, 1.0], "rmse": 0.5, "coverage_rmse": None,
                 "precision_rmse": None}
        return {"summary": {"splits": {"unseen": split, "ood": split}, "weights_sha256": None, "machine": "m",
                            "date": "d"}}

    monkeypatch.setattr(evaluate, "evaluate", fake_evaluate)
    monkeypatch.setattr(train, "run", lambda a: pytest.fail("a fixed goal trains nothing"))
    for split in ("train", "val", "unseen", "ood"):
        (tmp_path / "data" / split).mkdir(parents=True)
    monkeypatch.setattr("tax3d.sim.generate.generate", lambda a, progress=True: {"failed": []})
    monkeypatch.setattr("tax3d.cli.table._data_digests", lambda a, data: {})  # no demos in these folders
    args = Args(task="hangproccloth-unimodal", variants="floor,ceiling", out=tmp_path / "b", episodes=1,
                data=tmp_path / "data", keep=tmp_path / "keep", minutes=60)
    assert run(args) == 0
    assert [(a.goal, a.checkpoint, a.first_index) for a in asked] == [("mean", None, 100), ("demo", None, 100)]
    floor = json.loads((tmp_path / "keep" / "floor.json").read_text())
    assert floor["weights"] is None and floor["weights_sha256"] is None and floor["config"] is None
    assert floor["weights_chosen_on"] == "nothing: a fixed goal" and floor["preset"] is None


def test_an_unknown_row_is_one_line_naming_the_rows(tmp_path, capsys):
    from tax3d.cli import main

    assert main(["table", "--variants", "cd,floor,bogus", "--out", str(tmp_path / "b")]) == 2
    err = capsys.readouterr().err
    assert "--variants: unknown row 'bogus'" in err and "dp3, floor, ceiling" in err and len(err.splitlines()) == 1
    assert not (tmp_path / "b").exists()


def test_all_is_every_row_of_the_tasks_table(tmp_path):
    from tax3d.cli import table

    rows = table._check(Args(task="hangproccloth-multimodal", variants="all", out=tmp_path / "m"))
    assert rows == ["cd", "cp", "cd_w", "cp_w", "cd_nac", "cp_nac", "sd", "sp", "rd", "rp", "dp3", "floor", "ceiling"]
    rows = table._check(Args(task="hangbag", variants="all", out=tmp_path / "b"))
    assert "rd" not in rows and rows[-3:] == ["dp3", "floor", "ceiling"]


def test_a_kept_row_is_not_trained_or_scored_again_when_out_is_gone(tmp_path, monkeypatch, capsys):
    from tax3d.cli import eval as evaluate
    from tax3d.errors import UsageError

    monkeypatch.setattr(evaluate, "evaluate", lambda a, progress=True, record=True: pytest.fail("a kept row is scored once"))
    monkeypatch.setattr(train, "run", lambda a: pytest.fail("a kept row is trained once"))
    monkeypatch.setattr("tax3d.sim.generate.generate", lambda a, progress=True: {"failed": []})
    keep = tmp_path / "keep"
    keep.mkdir()
    split = {"episodes": 1, "success_rate": 1.0, "success_ci95": [0.2, 1.0], "rmse": 0.5, "coverage_rmse": None,
             "precision_rmse": None}
    kept = {"kind": "table-row", "task": "hangbag", "variant": "cd", "num_train": 16, "test": {"scorings": 1},
            "splits": {"unseen": split, "ood": split}}
    (keep / "cd.json").write_text(json.dumps(kept))
    args = Args(task="hangbag", variants="cd", out=tmp_path / "fresh", num_train=16, episodes=1,
                data=tmp_path / "data", keep=keep)
    assert run(args) == 0  # OUT never held the row (a fresh machine): the kept summary stands
    assert "scored before" in capsys.readouterr().out and json.loads((keep / "cd.json").read_text()) == kept

    args.rescore = True  # its weights were never in OUT: scoring again would mean training other weights
    with pytest.raises(UsageError, match=r"^--rescore: the weights cd was scored with are not in .*fresh/cd/train"):
        run(args)
    args.rescore = False

    args.num_train = 64  # the kept row belongs to another size: refused before any demonstration is made
    monkeypatch.setattr("tax3d.sim.generate.generate", lambda a, progress=True, record=True: pytest.fail("refused first"))
    with pytest.raises(UsageError, match=r"^--keep .*cd.json holds the row of hangbag with --num-train 16; expected"):
        run(args)


def test_the_demos_digest_follows_their_contents_not_their_files(generated, tmp_path):
    from tax3d.data.format import load_demo, save_demo

    demos, _ = generated
    first = demos_digest([demos / "demo_0.npz"])
    demo = load_demo(demos / "demo_0.npz")
    save_demo(tmp_path / "demo_0.npz", demo)  # the same demo written again, at another time
    assert demos_digest([tmp_path / "demo_0.npz"]) == first
    demo["flow"] = demo["flow"] + 1e-6
    save_demo(tmp_path / "demo_0.npz", demo)
    assert demos_digest([tmp_path / "demo_0.npz"]) != first
