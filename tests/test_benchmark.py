"""tax3d benchmark end to end at a tiny budget: each row trains, is chosen on val, scored once on the test episodes;
a stop between rows loses nothing and a rerun scores nothing twice unless asked."""

import json
import shutil

import pytest

from tax3d import train
from tax3d.benchmark import Args, run
from tax3d.checkpoint import sha256


@pytest.fixture
def data(generated, tmp_path):
    demos, _ = generated
    root = tmp_path / "data"
    for split, name in (("train", "demo_0"), ("val", "demo_0"), ("unseen", "demo_100"), ("ood", "demo_100")):
        (root / split).mkdir(parents=True)
        shutil.copy(demos / "demo_0.npz", root / split / f"{name}.npz")
    return root


def test_rows_are_scored_once_and_a_stop_between_rows_resumes(data, tmp_path, capsys, monkeypatch):
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


def test_one_budget_and_the_multimodal_recipe(tmp_path, capsys):
    from tax3d.benchmark import preset_of
    from tax3d.cli import main

    assert main(["benchmark", "--steps", "5", "--minutes", "3", "--out", str(tmp_path / "b")]) == 2
    assert "--steps 5: not with --minutes 3" in capsys.readouterr().err
    assert preset_of(Args(task="hangproccloth-multimodal")) == "cpu-multimodal"
    assert preset_of(Args(task="hangbag")) == "cpu" and preset_of(Args(task="hangbag", preset="paper")) == "paper"
