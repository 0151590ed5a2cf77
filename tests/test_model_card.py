"""Model cards: each shipped checkpoint's README.md is built by `python -m lab.results` from its config.json, kept
evaluation and kept log (docs/results/pages/model-cards.toml), and `python -m lab.results --check` catches a card that
drifted."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from lab.results.build import main
from tax3d.eval import ledger
from tax3d.kept import stamp
from tests.conftest import one_line_error, tiny_model

ROOT = Path(__file__).resolve().parents[1]


def evaluation(task: str, splits: dict, **extra) -> dict:
    return stamp("eval", 1, {"summary": {"task": task, "date": "2026-01-01", "machine": "m",
                                         "command": "tax3d eval --checkpoint runs/x/best", "splits": splits,
                                         **extra}})


def repository(tmp_path: Path, cards: list[dict], files: dict[str, dict]) -> Path:
    """A repository with docs/results (the paper's tables, a cards declaration, kept JSON); returns docs/results."""
    root = tmp_path / "docs" / "results"
    (root / "pages").mkdir(parents=True)
    shutil.copy(ROOT / "docs" / "results" / "paper.toml", root / "paper.toml")
    lines = ['kind = "cards"']
    for card in cards:
        lines += ["[[card]]", *[f"{key} = {json.dumps(value)}" for key, value in card.items()]]
    (root / "pages" / "model-cards.toml").write_text("\n".join(lines) + "\n")
    for rel, data in files.items():
        (root / rel).parent.mkdir(parents=True, exist_ok=True)
        (root / rel).write_text(json.dumps(data))
    return root


def checkpoint(tmp_path: Path, name: str, retired: dict | None = None, **settings) -> None:
    """A tiny checkpoint with the given settings; `retired` ({"train": {"time_limit": 45.0}}): fields of an earlier
    version's config.json, written into it."""
    model = tiny_model()
    for dotted, value in settings.items():
        section, key = dotted.split("__")
        setattr(getattr(model.config, section), key, value)
    model.save_pretrained(tmp_path / "checkpoints" / name)
    path = tmp_path / "checkpoints" / name / "config.json"
    data = json.loads(path.read_text())
    for section, values in (retired or {}).items():
        data[section].update(values)
    path.write_text(json.dumps(data, indent=2) + "\n")


def built(root: Path, name: str) -> str:
    assert main(["--root", str(root)]) == 0
    return (root.parent.parent / "checkpoints" / name / "README.md").read_text()


LOG = stamp("train-log", 2, {"source": "runs/x/log.jsonl", "records": [
    {"step": 1, "loss": 1.0, "seconds": 1.0, "plan": {"minutes": 30.0}},
    {"step": 2, "loss": 0.5, "seconds": 120.0, "val_rmse": 0.8},
    {"step": 3, "loss": 0.4, "seconds": 1800.0, "val_rmse": 0.6}]})


def test_model_card_is_built_from_the_checkpoint_log_and_evaluation(tmp_path, capsys):
    checkpoint(tmp_path, "tax3d-cd-x", data__task="hangproccloth-unimodal", data__train=("data/unimodal/train256",))
    splits = {"unseen": {"episodes": 40, "success_rate": 0.875, "rmse": 0.61, "coverage_rmse": 0.3},
              "ood": {"episodes": 40, "success_rate": 0.5, "rmse": 0.9, "coverage_rmse": None}}
    root = repository(tmp_path, [{"checkpoint": "checkpoints/tax3d-cd-x", "eval": "evals/x.json",
                                  "log": "training/x-log.json", "data": "DATA", "train": "TRAIN"}],
                      {"evals/x.json": evaluation("hangproccloth-unimodal", splits), "training/x-log.json": LOG})
    card = built(root, "tax3d-cd-x")
    assert card.startswith("# TAX3D-CD for hangproccloth-unimodal")
    # beside the paper's TAX3D-CD on unimodal (appendix D.2): success 0.90 / 0.85, RMSE 0.405 / 0.395
    assert "| unseen | 40 | 0.875 | 0.90 | 0.610 | 0.405 | 0.300 |" in card  # 35 of 40, exact
    assert "| ood | 40 | 0.50 | 0.85 | 0.900 | 0.395 | - |" in card
    assert "- steps: 3 (planned for 30 minutes)" in card and "- wall time: 30 minutes" in card
    assert "best validation RMSE: 0.600 at step 3" in card and "DATA\nTRAIN" in card
    assert "- training demonstrations: `data/unimodal/train256` (made by the first command below)" in card
    assert "grasped vertices" not in card  # the uniform weight goes unmentioned
    assert main(["--root", str(root), "--check"]) == 0

    # a card edited by hand, or one whose evaluation changed, differs from what the pages build
    readme = tmp_path / "checkpoints" / "tax3d-cd-x" / "README.md"
    readme.write_text(card.replace("0.875", "0.90"))
    capsys.readouterr()
    assert main(["--root", str(root), "--check"]) == 1
    assert "tax3d-cd-x/README.md differs" in capsys.readouterr().err
    readme.write_text(card)
    splits["ood"]["success_rate"] = 0.625
    (root / "evals" / "x.json").write_text(json.dumps(evaluation("hangproccloth-unimodal", splits)))
    assert main(["model-cards", "--root", str(root), "--check"]) == 1
    assert "tax3d-cd-x/README.md differs" in capsys.readouterr().err


def test_model_card_of_a_run_s_last_weights_names_them_beside_the_lowest_validation(tmp_path):
    checkpoint(tmp_path, "tax3d-cd-x", data__task="hangproccloth-multimodal", data__grip_weight=16.0)
    log = stamp("train-log", 2, {"source": "log", "records": [{"step": 2, "loss": 0.5, "seconds": 120.0,
                                                                "val_rmse": 0.8},
                                                               {"step": 3, "loss": 0.4, "seconds": 1800.0,
                                                                "val_rmse": 0.9}]})
    root = repository(tmp_path, [{"checkpoint": "checkpoints/tax3d-cd-x", "eval": "evals/x.json",
                                  "log": "training/x-log.json", "data": "DATA", "train": "TRAIN"}],
                      {"evals/x.json": evaluation("hangproccloth-multimodal", {"unseen": {
                          "episodes": 40, "success_rate": 0.5, "rmse": 1.0}}, checkpoint="runs/x/last"),
                       "training/x-log.json": log})
    card = built(root, "tax3d-cd-x")
    assert "- last validation RMSE: 0.900 at step 3 (these weights, the run's last); lowest: 0.800 at step 2" in card
    assert "best validation RMSE" not in card
    assert "; the grasped vertices weigh 16 in the loss" in card


def test_model_card_of_a_run_whose_log_was_not_kept_says_so(tmp_path):
    checkpoint(tmp_path, "tax3d-cp-x", data__task="hangbag", model__variant="cp", train__steps=4000,
               train__threads=1, retired={"train": {"time_limit": 45.0}})  # an earlier version's time limit
    root = repository(tmp_path, [{"checkpoint": "checkpoints/tax3d-cp-x", "eval": "evals/x.json", "data": "DATA",
                                  "train": "TRAIN"}],
                      {"evals/x.json": evaluation("hangbag", {"ood": {"episodes": 40, "success_rate": 0.8,
                                                                      "rmse": 0.5}})})
    card = built(root, "tax3d-cp-x")
    assert card.startswith("# TAX3D-CP for hangbag") and "| ood | 40 | 0.80 | 0.78 | 0.500 | 0.233 | - |" in card
    assert "- steps: a 4,000-step schedule, cut by a 45-minute limit on one core; the run's log was not kept" in card
    assert "wall time" not in card and "best validation" not in card


def test_model_card_of_a_checkpoint_trained_on_the_authors_data(tmp_path):
    checkpoint(tmp_path, "tax3d-cd-official", data__task="hangproccloth-simple", data__rotate=True)
    report = stamp("official-val", 1, {"command": "python -m lab.studies.official_report", "date": "2026-01-02",
                                       "machine": "n", "demos": 40, "samples": 5, "mean_goal_baseline_rmse": 1.1,
                                       "samplers": {"ddpm_100": {"rmse": 0.21, "rmse_min_of_samples": 0.19}}})
    root = repository(tmp_path, [{"checkpoint": "checkpoints/tax3d-cd-official", "eval": "evals/x.json",
                                  "official": "official_val.json", "data": "D", "train": "T"}],
                      {"evals/x.json": evaluation("hangproccloth-simple", {"unseen": {
                          "episodes": 40, "success_rate": 1.0, "rmse": 0.4}}), "official_val.json": report})
    card = built(root, "tax3d-cd-official")
    assert "trained on the authors' demonstrations" in card and "own demonstrations" not in card
    # beside the paper's TAX3D-CD on simple, unseen (appendix D.1): RMSE 0.255
    assert "| this checkpoint, 100-step DDPM | 0.210 | 0.190 |" in card
    assert "| the paper (`unseen`) | 0.255 | - |" in card
    assert "| mean goal of `train` (the floor) | 1.100 | - |" in card
    assert "Command: `python -m lab.studies.official_report`" in card
    assert "rotation augmentation" in card and "without rotation" not in card


@pytest.mark.parametrize("broken, says", [("eval", "expected a kept JSON of kind 'eval'"),
                                          ("official", "expected a kept JSON of kind 'official-val'"),
                                          ("checkpoint", "expected a `tax3d train` config.json")])
def test_model_card_bad_input_is_one_line_naming_the_file(tmp_path, capsys, broken, says):
    checkpoint(tmp_path, "ckpt")
    root = repository(tmp_path, [{"checkpoint": "checkpoints/ckpt", "eval": "evals/x.json",
                                  "official": "official_val.json", "data": "D", "train": "T"}],
                      {"evals/x.json": evaluation("hangproccloth-simple", {}),
                       "official_val.json": stamp("official-val", 1, {"samplers": {}})})
    target = {"eval": root / "evals" / "x.json", "official": root / "official_val.json",
              "checkpoint": tmp_path / "checkpoints" / "ckpt" / "config.json"}[broken]
    target.write_text("{not json")
    one_line_error(capsys, ["--root", root], str(target), "not valid JSON", says, main=main)
    assert not (tmp_path / "checkpoints" / "ckpt" / "README.md").exists()


def test_every_shipped_checkpoint_has_its_card_declared():
    declared = (ROOT / "docs" / "results" / "pages" / "model-cards.toml").read_text()
    for folder in sorted((ROOT / "checkpoints").iterdir()):
        assert f'checkpoint = "checkpoints/{folder.name}"' in declared, folder.name


def table_row(sha: str) -> dict:
    split = {"episodes": 40, "success_rate": 0.95, "success_ci95": [0.83, 0.99], "rmse": 0.34,
             "coverage_rmse": 0.24, "precision_rmse": 0.34}
    return stamp("table-row", 1, {
        "task": "hangproccloth-unimodal", "variant": "cd", "preset": "cpu", "minutes": 60.0, "num_train": 512,
        "weights": "best", "weights_chosen_on": "val", "weights_sha256": sha,
        "validations": [{"step": 10, "val_rmse": 0.5}, {"step": 20, "val_rmse": 0.3}, {"step": 25, "val_rmse": 0.31}],
        "test": {"first_index": 100, "episodes": 40, "samples": 5, "scorings": 1},
        "splits": {"unseen": split, "ood": {**split, "success_rate": 0.5, "success_ci95": [0.35, 0.65]}},
        "command": "tax3d benchmark --task hangproccloth-unimodal --variants cd --num-train 512 --minutes 60",
        "machine": "m", "date": "2026-01-03"})


def test_model_card_of_a_table_row_states_its_protocol_and_one_command(tmp_path, capsys):
    checkpoint(tmp_path, "tax3d-cd-x", data__task="hangproccloth-unimodal")
    sha = json.loads((tmp_path / "checkpoints" / "tax3d-cd-x" / "config.json").read_text())["weights_sha256"]
    card_spec = [{"checkpoint": "checkpoints/tax3d-cd-x", "row": "table/hangproccloth-unimodal/512/cd.json"}]
    row = table_row(sha)
    root = repository(tmp_path, card_spec, {"table/hangproccloth-unimodal/512/cd.json": row})
    card = built(root, "tax3d-cd-x")
    assert "demo_100-139, which no choice has touched, scored in no line of the ledger" in card  # the ledger counts
    line = ledger.scoring(row["task"], 512, "cd", {**row, "weights_sha256": sha}, None, 100, row["command"])
    ledger.append(root / "table" / "ledger.jsonl", line)
    card = built(root, "tax3d-cd-x")
    assert "trained on 512 of this project's demonstrations (the paper trains on 64)" in card
    assert "`unseen` and `ood` demo_100-139, which no choice has touched, scored once" in card
    # beside the paper's TAX3D-CD on unimodal (appendix D.2): success 0.90 / 0.85, RMSE 0.405 / 0.395
    assert "| unseen | 40 | 0.95 (0.83-0.99) | 0.90 | 0.340 | 0.405 | 0.240 | 0.340 |" in card
    assert "| ood | 40 | 0.50 (0.35-0.65) | 0.85 |" in card
    assert "weights chosen on `val`: these are the run's best weights, validation RMSE 0.300 at step 20" in card
    assert "```bash\ntax3d table --task hangproccloth-unimodal --variants cd" in card
    assert "The row records it under the command's earlier name: `tax3d benchmark --task hangproccloth-unimodal" in card
    assert "On the same episodes" not in card  # no floor or ceiling scored yet
    assert main(["--root", str(root), "--check"]) == 0
    ledger.append(root / "table" / "ledger.jsonl", line)  # scored again: the row's file may say once, the ledger not
    assert "which no choice has touched, scored 2 times" in built(root, "tax3d-cd-x")

    # the floor and ceiling of the same table, once scored, bound the card's success
    for key, unseen, ood in (("floor", 0.35, 0.3), ("ceiling", 0.9, 0.875)):
        bound = table_row(None)
        bound["splits"]["unseen"]["success_rate"], bound["splits"]["ood"]["success_rate"] = unseen, ood
        (root / f"table/hangproccloth-unimodal/512/{key}.json").write_text(json.dumps({**bound, "variant": key}))
    card = built(root, "tax3d-cd-x")
    assert ("On the same episodes (unseen / ood), the mean goal of train (the floor) hangs 0.35 / 0.30 and each "
            "demo's own goal (the ceiling) hangs 0.90 / 0.875.") in card

    # the checkpoint's weights must be the row's: another sha is a one-line error naming both
    (root / "table/hangproccloth-unimodal/512/cd.json").write_text(json.dumps(table_row("0" * 64)))
    one_line_error(capsys, ["model-cards", "--root", root], "tax3d-cd-x/config.json", "0" * 64,
                   "the weights of the row", main=main)
