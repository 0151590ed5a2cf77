"""`python -m lab.results`: pages built from declarations and kept JSON (the task pages and the measurement pages),
--check (plots by what they are drawn from), bad input (a kept JSON of another kind or version), the paper's data
file."""

from __future__ import annotations

import json
import re
import shutil
import tomllib
from pathlib import Path

import pytest

from lab.results import kept
from lab.results.build import build, declaration, main
from lab.results.pages import plots
from lab.results.pages.page import PLACEHOLDER, SPLITS, shared
from lab.results.pages.task import TaskPage
from tax3d.kept import stamp
from tests.conftest import one_line_error

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "docs" / "results"

PAGE = '''
title = "Fixture task"
task = "hangproccloth-unimodal"
headline = ["cd", "paper:CD", "floor"]
readme = { task = "Fixture", row = "cd", paper = "CD", order = 1 }
verdict = "TAX3D-CD hangs {cd.unseen.success} of `unseen` cloths against the paper's {paper.CD.success.unseen}."
definitions = "RMSE and success as defined."

[[note]]
title = "Reading the table"
text = "The floor hangs {floor.ood.success} of `ood` cloths; TAX3D-CD's RMSE there is {cd.ood.rmse:.3f}."

[[row]]
id = "cd"
label = "TAX3D-CD, cpu preset, fixture"
summary = "evals/cd.json"
paper = "CD"
made = "tax3d train --preset cpu --out runs/cd"

[[row]]
id = "floor"
label = "mean goal of train (the floor)"
summary = "evals/floor.json"

[[curve]]
id = "cd-curve"
label = "TAX3D-CD"
summary = "evals/cd-curve.json"
'''


def eval_summary(success: float, rmse: float) -> dict:
    split = {"episodes": 20, "success_rate": success, "rmse": rmse, "coverage_rmse": rmse / 2,
             "precision_rmse": rmse, "predict_seconds": 0.5, "sim_seconds": 4.0, "failed_runs": 0}
    return stamp("eval", 1, {"summary": {
        "checkpoint": "runs/cd/best", "task": "hangproccloth-unimodal", "command": "tax3d eval ...",
        "machine": "test machine", "date": "2026-01-01", "policy_offset": [0.0, 0.0, 0.0],
        "splits": {k: dict(split) for k in SPLITS}}})


@pytest.fixture
def root(tmp_path: Path) -> Path:
    """A results folder: the paper's data file, one page declaration and its kept summaries."""
    (tmp_path / "pages").mkdir()
    (tmp_path / "evals").mkdir()
    shutil.copy(RESULTS / "paper.toml", tmp_path / "paper.toml")
    (tmp_path / "pages" / "fixture.toml").write_text(PAGE)
    (tmp_path / "evals" / "cd.json").write_text(json.dumps(eval_summary(0.75, 0.8125)))
    floor = stamp("fixed-goal", 1, {
        "command": "python scripts/oracle_policy.py --goal mean", "goal": "mean", "offset": [0.0, 0.0, 0.0],
        "machine": "test machine", "date": "2026-01-02",
        "splits": {k: {"episodes": 20, "success_rate": 0.25, "rmse": 1.5} for k in SPLITS}})
    (tmp_path / "evals" / "floor.json").write_text(json.dumps(floor))
    curve = stamp("val-curve", 1, {"run": "runs/cd", "val": ["data/u/unseen"], "val_demos": 10, "val_samples": 2,
                                   "steps": 2000, "points": [{"step": 1000, "val_rmse": 2.5},
                                                             {"step": 2000, "val_rmse": 1.25}]})
    (tmp_path / "evals" / "cd-curve.json").write_text(json.dumps(curve))
    return tmp_path


def test_page_from_fixture_summaries(root, capsys):
    assert main(["--root", str(root)]) == 0
    text = (root / "fixture.md").read_text()
    assert text.startswith("# Fixture task\n\nTAX3D-CD hangs 0.75 of `unseen` cloths against the paper's 0.90.\n")
    assert "| TAX3D-CD, cpu preset, fixture | 0.75 | 0.75 | 0.75 | 0.812 | 0.812 | 0.812 | 20 / 20 / 20 |" in text
    assert "| TAX3D-CD, the paper | 0.94 | 0.90 | 0.85 | 0.052 | 0.405 | 0.395 | 64 / 40 / 40 |" in text
    assert "| mean goal of train (the floor) | 0.25 | 0.25 | 0.25 | 1.500 | 1.500 | 1.500 | 20 / 20 / 20 |" in text
    assert "The floor hangs 0.25 of `ood` cloths; TAX3D-CD's RMSE there is 0.812." in text
    assert "| 2,000 | 1.250 |" in text  # the validation curve
    assert "`tax3d train --preset cpu --out runs/cd`" in text and "test machine, 2026-01-01" in text
    assert (root / "fixture.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert main(["--root", str(root), "--check"]) == 0


def test_what_every_page_says_comes_from_the_shared_text(root, capsys):
    """A fixed-goal row, a table row's source and a shared note need no text of their own; a source that is no
    table row does."""
    page = root / "pages" / "fixture.toml"
    text = page.read_text().replace('label = "mean goal of train (the floor)"\n', "")
    (root / "table" / "another-task" / "64").mkdir(parents=True)
    shutil.copy(root / "evals" / "floor.json", root / "table" / "another-task" / "64" / "floor.json")
    page.write_text(text + '\n[[source]]\nid = "floor64"\nsummary = "evals/floor.json"\n'
                    '[[source]]\nid = "again"\nsummary = "evals/floor.json"\n'
                    '[[note]]\nshared = "redraw"\nfirst = "floor"\nagain = "again"\n')
    assert main(["--root", str(root)]) == 2
    assert "source 'floor64': no label" in capsys.readouterr().err
    page.write_text(page.read_text().replace('summary = "evals/floor.json"\n[[source]]',
                                             'summary = "table/another-task/64/floor.json"\n[[source]]'))
    assert main(["--root", str(root)]) == 0, capsys.readouterr().err
    built = (root / "fixture.md").read_text()
    assert "| mean goal of train in the anchor frame (the floor) | 0.25 |" in built
    assert "RMSE: world frame" in built and "judged by the success check of appendix A.4.2" in built
    assert "- the floor row at 64 demos ([table/another-task/64/floor.json]" in built
    assert "- the floor on the `unseen` test episodes regenerated on the second machine" in built
    task = TaskPage(page, root, tomllib.loads((root / "paper.toml").read_text()), declaration(page))
    assert task.notes("table")[0].startswith("**Two machines, two draws of the demonstrations.** The rows dated "
                                             "2026-01-02 ran on test machine; the later ones on test machine")


def test_plot_is_the_same_on_every_run(root):
    first = build(root)
    assert first == build(root)


def test_check_compares_a_plot_by_what_it_is_drawn_from(root, capsys):
    """Another matplotlib draws other pixels from the same data: --check passes; other data: it names the plot."""
    assert main(["--root", str(root)]) == 0
    png = root / "fixture.png"
    source = plots.drawn_from(png.read_bytes())
    assert source["plot"] == "success-bars" and source["success"][0] == [0.75, 0.75, 0.75]
    fig = plots._figure(2.0, 2.0)
    png.write_bytes(plots._png(fig, source))  # other pixels, the same data
    assert main(["--root", str(root), "--check"]) == 0
    png.write_bytes(plots._png(fig, {**source, "success": [[0.5, 0.75, 0.75], *source["success"][1:]]}))
    capsys.readouterr()
    assert main(["--root", str(root), "--check"]) == 1
    assert "fixture.png differs" in capsys.readouterr().err


@pytest.mark.parametrize("change, says", [
    ({"kind": "summary"}, "kind 'summary'; expected a kept JSON of kind 'eval' or 'fixed-goal'"),
    ({"version": 9}, "'eval' of version 9; expected version 1, as `tax3d eval` (OUT/summary.json) writes it"),
    ({"kind": None}, "kind None; expected a kept JSON of kind 'eval' or 'fixed-goal'")])
def test_kept_json_of_another_kind_or_version_is_a_one_line_error(root, capsys, change, says):
    path = root / "evals" / "cd.json"
    data = {**json.loads(path.read_text()), **change}
    path.write_text(json.dumps({k: v for k, v in data.items() if v is not None}))
    one_line_error(capsys, ["--root", root], str(path), says, main=main)


def test_a_long_note_or_verdict_is_a_one_line_error(root, capsys):
    page = root / "pages" / "fixture.toml"
    text = page.read_text()
    page.write_text(text.replace('text = "The floor hangs', 'text = "' + "word " * 60 + 'The floor hangs'))
    one_line_error(capsys, ["--root", root], "note 'Reading the table'", "expected at most 50", main=main)
    page.write_text(text.replace("against the paper's {paper.CD.success.unseen}.",
                                 "against the paper's {paper.CD.success.unseen}. One. Two."))
    one_line_error(capsys, ["--root", root], "verdict: 3 sentences; expected at most 2", main=main)
    page.write_text(text.replace('headline = ["cd", "paper:CD", "floor"]', ""))
    one_line_error(capsys, ["--root", root], "fixture.toml: no headline", main=main)


def test_check_names_a_page_whose_summary_changed(root, capsys):
    assert main(["--root", str(root)]) == 0
    (root / "evals" / "cd.json").write_text(json.dumps(eval_summary(0.5, 0.8125)))
    capsys.readouterr()
    assert main(["--root", str(root), "--check"]) == 1
    err = capsys.readouterr().err
    assert "fixture.md differs" in err
    assert main(["fixture", "--root", str(root), "--check"]) == 1


def test_missing_summary_names_the_row(root, capsys):
    (root / "evals" / "floor.json").unlink()
    assert main(["--root", str(root)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "row 'floor'" in err and "evals/floor.json not found" in err
    assert not (root / "fixture.md").exists()


@pytest.mark.parametrize("argv, words", [(["nope"], "page 'nope': expected one of fixture"),
                                        (["--root", "/nonexistent"], "--root /nonexistent: expected a results folder")])
def test_bad_options_are_one_line_exit_2(root, capsys, argv, words):
    assert main(argv + ([] if "--root" in argv else ["--root", str(root)])) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and words in err, err


def test_placeholder_without_a_value_is_an_error(root, capsys):
    page = root / "pages" / "fixture.toml"
    page.write_text(page.read_text().replace("{cd.ood.rmse:.3f}", "{cd.ood.nothing}"))
    assert main(["--root", str(root)]) == 2
    assert "placeholder {cd.ood.nothing}" in capsys.readouterr().err


def test_paper_data_file_against_the_paper_text():
    # Typed from the tables of the paper's appendix D, independently of docs/results/paper.toml.
    paper = tomllib.loads((RESULTS / "paper.toml").read_text())
    assert paper["hangproccloth-unimodal"]["rows"]["CD"]["success"] == [0.94, 0.90, 0.85]
    assert paper["hangproccloth-unimodal"]["rows"]["CP-W"]["rmse"][2] == 19.923
    assert paper["hangproccloth-simple"]["rows"]["SP"]["success"] == [0.50, 0.58, 0.05]
    assert paper["hangproccloth-simple"]["rows"]["CD"]["rmse"] == [0.270, 0.255, 0.498]
    assert paper["hangproccloth-multimodal"]["rows"]["RP"]["coverage"] == [1.360, 1.417, 1.432]
    assert paper["hangproccloth-multimodal"]["rows"]["CP-W"]["precision"][2] == 47.372
    assert paper["hangproccloth-multimodal"]["rows"]["RD"]["success"] == [0.53, 0.60, 0.50]
    assert paper["hangbag"]["rows"]["CP-NAC"]["rmse"] == [1.485, 1.487, 1.486]
    assert paper["hangbag"]["rows"]["CP"]["success"] == [0.94, 0.93, 0.78]
    assert "rmse" not in paper["hangbag"]["rows"]["DP3"]
    assert paper["training"]["epochs"] == 20000


def _prose(text: str) -> list[str]:
    """The paragraphs outside <details>, tables, headings, images and comments."""
    text = re.sub(r"<details>.*?</details>|<!--.*?-->\n?", "", text, flags=re.S)
    return [p for p in text.split("\n\n") if p.strip() and not p.lstrip().startswith(("|", "#", "!["))]


def test_no_paragraph_over_120_words_outside_details():
    built = build(RESULTS)
    assert {p.name for p in built} >= {"hangproccloth-sim.md", "official-simple.md", "training.md"}
    for path, data in built.items():
        if path.suffix == ".md" and path.name != "README.md":
            text = data.decode()
            if "<!-- study -->" in text:  # docs/results/training.md: the section `python -m lab.results` builds
                text = text.split("<!-- study -->", 1)[1].split("<!-- /study -->", 1)[0]
            for paragraph in _prose(text):
                assert len(paragraph.split()) <= 120, f"{path.name}: {paragraph[:80]}..."


def test_notes_have_no_hand_typed_numbers():
    """A number in a verdict or note comes from a kept summary through a placeholder."""
    texts = [("shared.toml", n["text"]) for n in shared()["note"].values()]
    for file in sorted((RESULTS / "pages").glob("*.toml")):
        spec = tomllib.loads(file.read_text())
        own = [spec.get("verdict", ""), spec.get("sets_note", ""), spec.get("spread_note", "")]
        own += [n["text"] for n in spec.get("note", []) + spec.get("detail", []) if "shared" not in n]
        own += [d["what"] for d in spec.get("difference", [])]
        texts += [(file.name, text) for text in own]
    for name, text in texts:
        bare = re.sub(r"`[^`]*`|\]\([^)]*\)|\b(TAX3D|DP3)\b", "", PLACEHOLDER.sub("", text))
        assert not re.search(r"\d", bare), f"{name}: a hand-typed number in {bare[:200]!r}"


def test_committed_pages_are_what_lab_results_builds(capsys):
    assert main(["--check"]) == 0, capsys.readouterr().err


def test_each_task_page_opens_with_its_verdict_then_the_table():
    for file in sorted((RESULTS / "pages").glob("*.toml")):
        if "kind" in tomllib.loads(file.read_text()):
            continue
        lines = (RESULTS / f"{file.stem}.md").read_text().split("\n")
        assert lines[0].startswith("# ") and lines[1] == "" and lines[3] == "", file.stem
        assert lines[4].startswith(("| |", "## The paper's table")), file.stem


def test_every_kept_json_declares_a_kind_that_loads():
    """Each kept file under docs/results/ but a run's config.json names its kind and a version that is read."""
    for path in sorted(RESULTS.rglob("*.json")):
        data = json.loads(path.read_text())
        if all(key in data for key in kept.CONFIG_SECTIONS):
            kept.config(path)
        else:
            kept.load(path)


def test_every_writer_stamps_a_kind_and_version_that_the_pages_read():
    """Each `kept.stamp(KIND, VERSION, ...)` of the package, the benchmarks and the lab writes what KINDS reads, at
    the last version it reads."""
    stamps = [m for folder in ("src", "benchmarks", "lab") for path in sorted((ROOT / folder).rglob("*.py"))
              for m in re.finditer(r'kept\.stamp\("([a-z-]+)", (\d+),', path.read_text())]
    assert len(stamps) >= 20
    for m in stamps:
        assert m.group(1) in kept.KINDS and int(m.group(2)) == kept.KINDS[m.group(1)][0][-1], m.group(0)


def test_a_kept_command_renamed_or_moved_since_shows_what_runs_it_today():
    from lab.results.commands import renamed, shown

    today = "(recorded with an earlier version; today: {} with the same options)"
    assert renamed("tax3d benchmark --task hangbag --keep k") == "tax3d table --task hangbag --keep k"
    table = today.format("`tax3d table`")
    assert shown("tax3d benchmark --task hangbag") == f"`tax3d benchmark --task hangbag` {table}"
    assert shown("tax3d benchmark --tusk x").endswith("today: `tax3d table`)")  # an option since retired
    assert shown("tax3d results hangbag").endswith(today.format("`python -m lab.results`"))
    study = today.format("`python -m lab.studies.mode_spread`")
    assert shown("python benchmarks/mode_spread.py --data d") == f"`python benchmarks/mode_spread.py --data d` {study}"
    for current in ("tax3d table --task hangbag", "python benchmarks/sim.py", "python -m lab.studies.mode_spread"):
        assert shown(current) == f"`{current}`"


# -- the measurement pages: the simulation page, the official-data page, the training study -------------------------

PROV = {"machine": "fixture machine", "date": "2026-02-03"}


def regularised() -> dict:
    out = {**study({name: [(m * 8, 1.2 - m / 10) for m in range(1, 5)]
                    for name in ("v-wd01-30min", "v-fresh-subsets-30min")}), "minutes": 30.0}
    out["runs"]["v-wd01-30min"]["config"]["train"] = {"weight_decay": 0.1}
    return out


def points() -> dict:
    out = {**study({name: [(m * 15, 1.3 - m / 10) for m in range(1, 7)]
                    for name in ("v-preset-90min", "v-512pts-90min")}), "minutes": 90.0}
    for name, count in (("v-preset-90min", 256), ("v-512pts-90min", 512)):
        out["runs"][name]["config"]["data"] = {"num_action_points": count}
    return out


def demos() -> dict:
    return {**study({name: [(m * 10, 1.5 - m / 10) for m in range(1, 7)]
                     for name in ("v-64demos-60min", "v-256demos-60min")}), "minutes": 60.0}


def eight_times() -> dict:
    out = {**study({"v-256demos-60min": [(m * 10, 1.3 - m / 10) for m in range(1, 7)],
                    "v-512demos-60min": [(m * 9, 1.5 - m / 10) for m in range(1, 7)]}), "minutes": 60.0}
    out["runs"]["v-512demos-60min"].update(minutes=54.0, plan={"step_seconds": 0.625})
    out["runs"]["v-512demos-60min"]["config"]["data"] = {"train_size": 400}
    return out


def grip_weights() -> dict:
    out = {**study({"v-grip16-60min": [(m * 12, 1.5 - m / 10) for m in range(1, 7)],
                    "v-grip128-60min": [(m * 13, 1.6 - m / 10) for m in range(1, 7)]}), "minutes": 60.0}
    for name, weight in (("v-grip16-60min", 16.0), ("v-grip128-60min", 128.0)):
        out["runs"][name]["config"]["data"] = {"grip_weight": weight}
        out["runs"][name]["minutes"] = 70.0
        for point in out["runs"][name]["curve"]:
            point["val_grip_error"] = point["val_rmse"] / 2
    return out


def finalist() -> dict:
    out = {**study({"v-grip16-512demos-120min": [(m * 17, 1.4 - m / 10) for m in range(1, 7)]}), "minutes": 120.0}
    run = out["runs"]["v-grip16-512demos-120min"]
    run["config"]["data"], run["minutes"] = {"grip_weight": 16.0, "train_size": 400}, 104.0
    for point in run["curve"]:
        point["val_grip_error"] = point["val_rmse"] / 2
    return out


def hour_pair(first: tuple[str, float, int], second: tuple[str, float, int], data: dict) -> dict:
    """Two hour-long runs, each (name, minutes between validations, validations); the first run's config gets `data`."""
    out = {**study({name: [(m * every, 1.3 - m / 10) for m in range(1, count + 1)]
                    for name, every, count in (first, second)}), "minutes": 60.0}
    out["runs"][first[0]]["config"]["data"] = data
    return out


def multimodal_finalist(name: str | tuple[str, ...], validations: int = 6) -> dict:
    names = (name,) if isinstance(name, str) else name
    out = {**study({n: [(m * 15, 1.4 - m / 10) for m in range(1, validations + 1)] for n in names}), "minutes": 110.0}
    for n in names:
        out["runs"][n]["minutes"] = 100.0
        for point in out["runs"][n]["curve"]:
            point["val_coverage_rmse"] = point["val_rmse"] - 0.25
    return out


def gripped_policy(unseen: float, ood: float, grip: float) -> dict:
    out = policy(unseen, ood)
    for split in out["summary"]["splits"].values():
        split.update(rmse=0.5, executed_grip_error=grip)
    return out


def finalist_policy() -> dict:
    out = gripped_policy(0.875, 0.825, 0.2)
    out["summary"]["splits"]["train"] = {"episodes": 40, "success_rate": 0.975, "rmse": 0.25}
    return out


def multimodal_demos() -> dict:
    out = demos()
    for run in out["runs"].values():
        for point in run["curve"]:
            point["val_coverage_rmse"] = point["val_rmse"] - 0.25
    return out


def policy(unseen: float, ood: float) -> dict:
    return {"summary": {**PROV, "command": "tax3d eval ...", "splits": {
        "unseen": {"episodes": 40, "success_rate": unseen}, "ood": {"episodes": 40, "success_rate": ood}}}}


def set_policy(train: float, unseen: float, ood: float, precision: float) -> dict:
    """A multimodal policy's summary with every split and its precision RMSE."""
    out = policy(unseen, ood)
    out["summary"]["splits"]["train"] = {"episodes": 40, "success_rate": train}
    for split in out["summary"]["splits"].values():
        split["precision_rmse"] = precision
    return out


def study(curves: dict[str, list[tuple[float, float]]]) -> dict:
    return {**PROV, "val": ["v"], "val_demos": 20, "val_samples": 2, "runs": {
        name: {"options": f"--opt {name}", "command": f"tax3d train --out runs/{name}", "steps_per_minute": 100.0,
               "plan": {"step_seconds": 0.5}, "steps": int(curve[-1][0] * 100), "config": {"model": {"hidden_size": 8}},
               "curve": [{"minutes": m, "step": int(m * 100), "val_rmse": r, "val_rmse_mean": r + 0.25,
                          "train_mse": r / 10} for m, r in curve]}
        for name, curve in curves.items()}}


def sampler(rmse: float) -> dict:
    return {"rmse": rmse, "rmse_per_sample_index": [rmse, rmse], "rmse_min_of_samples": rmse / 2,
            "rmse_median_demo": rmse, "rmse_max_demo": 2 * rmse}


def measurement_json() -> dict[str, dict]:
    """Small kept JSON for the three measurement pages, by path relative to the results folder."""
    split = {"demos": 4, "init_max_abs_diff": 2e-05, "anchor_nn_mean": 0.001, "anchor_nn_max": 0.002, "episodes": 2,
             "expert_success": 0.5, "goal_rmse_mean": 0.25, "goal_rmse_median": 0.2, "goal_rmse_max": 0.75,
             "goal_rmse_under_0.5": 1}
    rate = {"task": "hangproccloth-simple", "split": "unseen", "episodes": 4, "exploded": 1, "success_rate": 0.75,
            "seconds_per_episode": 12.5}
    speed = {**PROV, "command": "python benchmarks/sim.py", "task": "hangproccloth-simple",
             "sim_steps_per_second": 640.0,
             "seconds_per_episode_1_worker": 8.5, "throughput_ratio_2_workers": 1.5}
    predict = {"action_points": 580, "ddpm_100": {"latency_s": 0.5, "rmse_min_of_samples": 0.25},
               "ddpm_10": {"latency_s": 0.05, "rmse_min_of_samples": 0.25},
               "ddim_10": {"latency_s": 0.04, "rmse_min_of_samples": 0.25}, "speedup_10_vs_100": 10.0,
               "rmse_ratio_ddpm_10_vs_100": 1.0, "samples_per_demo": 3, "latency_rounds": 5}
    return {
        "fidelity.json": {**PROV, "command": "python scripts/fidelity.py", "train": split, "val": split},
        "expert_rates.json": {**PROV, "command": "python scripts/expert_rates.py", "rates": [rate]},
        "expert_rates_random.json": {**PROV, "command": "python scripts/expert_rates.py --num 4", "rates": [rate]},
        "sim_benchmark.json": speed,
        "sim_benchmark_hangbag.json": {**speed, "task": "hangbag", "throughput_ratio_2_workers": None},
        "official_val.json": {**PROV, "command": "python scripts/official_report.py", "checkpoint": "checkpoints/x",
                              "demos": 8, "samples": 2, "mean_goal_baseline_rmse": 1.25,
                              "samplers": {"ddpm_100": sampler(0.125), "ddim_10": sampler(0.375)}},
        "model_benchmark.json": {**PROV, "command": "python benchmarks/model.py", "matmul_peak_gflops": 100.0,
                                 "train_step": {"config": "paper", "seconds": 1.0, "gflop": 50.0, "gflops": 50.0,
                                                "fraction_of_peak": 0.5}},
        "predict_benchmark.json": {**PROV, "command": "python benchmarks/model.py --parts predict,large",
                                   "predict": predict, "large_clouds": {
            "action_points": 20000, "network_points": 256, "latency_s": 0.25, "demos": 8, "samples_per_demo": 2,
            "rmse_sampled": 0.25, "rmse_every_point": 0.2, "rmse_ratio_sampled_vs_every_point": 1.25}},
        "official_training.json": {**PROV, "command": "tax3d train --preset cpu --out runs/o", "run": "runs/o",
                                   "variant": "cd", "val": ["v"], "val_demos": 4, "val_samples": 2, "steps": 900,
                                   "source": "runs/o/log.jsonl", "records": [
                                       {"step": 300, "val_rmse": 0.5, "seconds": 600.0},
                                       {"step": 600, "val_rmse": 0.25, "seconds": 1200.0},
                                       {"step": 900, "val_rmse": 0.375, "seconds": 1800.0}]},
        "training/ttq-1.json": study({"a": [(14, 2.0), (29, 1.5), (61, 0.9)], "b": [(20, 1.2), (65, 0.7)],
                                      "shipped": [(30, 1.2), (62, 0.6)]}),
        "training/ttq-5.json": {**study({"v-loss-30min": [(8, 1.9), (15, 1.6), (22, 1.5), (30, 1.25)]}),
                                "minutes": 30.0},
        "training/ttq-6.json": {**study({name: [(m * k, 1.5 - m / 10) for m in range(1, 7)]
                                         for name, k in (("v-95min", 16), ("v-128x3-95min", 18))}), "minutes": 95.0},
        "training/ttq-7.json": {**study({"v-rotate-95min": [(m * 16, 1.4 - m / 10) for m in range(1, 7)]}),
                                "minutes": 95.0},
        "training/ttq-8.json": regularised(),
        "training/ttq-9.json": points(),
        "training/ttq-10.json": demos(),
        "training/ttq-12.json": eight_times(),
        "training/ttq-13.json": grip_weights(),
        "training/ttq-14.json": finalist(),
        "evals/unimodal-cd-cpu-v-grip16-512demos-120min.json": finalist_policy(),
        "evals/unimodal-cd-cpu-v-grip16-60min-unseen-ood.json": gripped_policy(0.875, 0.75, 0.125),
        "evals/unimodal-cd-cpu-v-grip128-60min.json": gripped_policy(0.75, 0.75, 0.25),
        "evals/unimodal-cd-cpu-v-256demos-60min-rerun.json": gripped_policy(0.625, 0.5, 0.375),
        "training/multimodal-ttq-11.json": multimodal_demos(),
        "evals/multimodal-cd-cpu-v-256demos-60min.json": policy(0.5, 0.25),
        "evals/multimodal-cd-cpu-85min.json": policy(0.25, 0.125),
        "training/multimodal-ttq-16.json": multimodal_finalist("v-grip16-512demos-110min"),
        "training/multimodal-ttq-16-rotate.json": multimodal_finalist("v-grip16-rotate-512demos-110min"),
        "evals/multimodal-cd-cpu-v-grip16-512demos-110min.json": policy(0.625, 0.675),
        "evals/multimodal-cd-cpu-v-grip16-rotate-512demos-110min.json": policy(0.55, 0.55),
        "training/ttq-17.json": {**multimodal_finalist("v-grip16-all512-110min", 7), "val": ["v"]},
        "evals/unimodal-cd-cpu-v-grip16-all512-110min.json": gripped_policy(0.875, 0.85, 0.2),
        "training/multimodal-ttq-17.json": multimodal_finalist("v-grip16-all506-110min", 7),
        "evals/multimodal-cd-cpu-v-grip16-all506-110min.json": set_policy(0.65, 0.7, 0.675, 0.94),
        "training/multimodal-ttq-18-mean.json": multimodal_finalist("v-grip16-mean-all506-95min", 2),
        "training/multimodal-ttq-18-x0.json": {**multimodal_finalist("x0-grip16-all506-60min", 4), "minutes": 60.0},
        "training/multimodal-ttq-18-cp.json": multimodal_finalist("cp-grip16-all506-100min"),
        "evals/multimodal-cd-cpu-x0-grip16-all506-60min.json": set_policy(0.875, 0.8, 0.7, 0.55),
        "training/ttq-19.json": {**study({"x0-grip16-60min": [(m * 10, 1.4 - m / 10) for m in range(1, 7)]}),
                                 "minutes": 60.0},
        "training/ttq-20.json": {**study({name: [(m * 4, 1.4 - m / 10) for m in range(1, 8)]
                                          for name in ("v-grip16-30min", "vcap5-grip16-30min")}), "minutes": 30.0},
        "training/multimodal-ttq-19.json": {**multimodal_finalist("x0-grip16-all506-85min"), "minutes": 85.0},
        "evals/multimodal-cd-cpu-x0-grip16-all506-85min.json": set_policy(0.9, 0.875, 0.675, 0.45),
        "evals/multimodal-cp-cpu-v-grip16-all506-100min.json": set_policy(0.4, 0.425, 0.55, 1.1),
        "training/multimodal-ttq-21.json": multimodal_finalist(
            ("x0-grip16-all506-110min", "vcap-grip16-all506-110min"), 8),
        "evals/multimodal-cd-cpu-x0-grip16-all506-110min.json": set_policy(0.925, 0.925, 0.825, 0.45),
        "evals/multimodal-cd-cpu-vcap-grip16-all506-110min.json": set_policy(0.95, 0.875, 0.8, 0.4),
        "training/ttq-22.json": {**study({name: [(m * 17, 1.4 - m / 10) for m in range(1, 8)]
                                          for name in ("v-grip16-all512-120min", "vcap-grip16-all512-120min")}),
                                 "minutes": 120.0},
        "evals/unimodal-cd-cpu-v-grip16-all512-120min.json": finalist_policy(),
        "evals/unimodal-cd-cpu-vcap-grip16-all512-120min.json": finalist_policy(),
        "evals/unimodal-demo-goal-40ep.json": policy(0.9, 0.9),
        "evals/unimodal-cd-cpu-95min-v.json": policy(0.65, 0.65),
        "evals/unimodal-cd-cpu-v-rotate-95min.json": policy(0.6, 0.55),
        "training/ttq-2.json": {**study({"eps-subsets-ema": [(15, 1.1), (60, 0.55)]}), "minutes": 60.0},
        "training/ttq-4.json": {**study({"v-loss": [(15, 0.65), (60, 0.5)]}), "minutes": 60.0},
        "training/ttq-23.json": hour_pair(("v-grip16-scale04-60min", 15, 4), ("v-grip16-60min", 12, 5),
                                          {"target_scale": 0.4}),
        "training/hangbag-ttq-24.json": hour_pair(("v-grip16-60min", 7, 8), ("eps-60min", 6.5, 9),
                                                  {"grip_weight": 16.0}),
        "training/ttq-25.json": {**study({name: [(m * 4, 1.4 - m / 10) for m in range(1, 8)]
                                          for name in ("minsnr-grip16-30min", "vcap-grip16-30min")}), "minutes": 30.0},
        "evals/hangbag-cd-cpu-v-grip16-60min.json": gripped_policy(0.9, 0.85, 0.1),
        "evals/hangbag-cd-cpu-eps-60min.json": gripped_policy(0.8, 0.75, 0.2),
        "evals/hangbag-cd-cpu-90min.json": finalist_policy(),
        "evals/unimodal-cd-cpu-v-grip16-60min-ttq23.json": gripped_policy(0.9, 0.8, 0.2),
        "evals/unimodal-cd-cpu-v-grip16-scale04-60min.json": gripped_policy(0.85, 0.775, 0.2),
        "training/unimodal-floor-20.json": {**PROV, "command": "tax3d predict ...", "rmse_mean_goal_baseline": 1.75},
        **{f"evals/unimodal-cd-cpu-95min-v-samplers-{split}.json": {
            **PROV, "command": "tax3d predict ... --compare-samplers", "samples": 5, "demos": 40, "steps": 100,
            "samplers": {name: {"rmse_mean": 0.5} for name in ("ddpm_10", "ddim_10", "ddpm_100")}}
           for split in ("unseen", "ood")},
        "precision_benchmark.json": {**PROV, "command": "python benchmarks/model.py --parts precision", "precision": {
            "cpu": {"speedup_bf16": 0.5}, "paper": {"speedup_bf16": 1.5}}},
        "fps_benchmark_fpsample.json": {**PROV, "command": "python benchmarks/fps.py", "machine": "fixture machine",
                                        "fpsample": {"speedup_per_sample_over_numpy": 2.0,
                                                     "real_clouds": {"clouds": 8, "same_indices": 3}},
                                        "numpy_real_clouds": {"clouds": 8, "same_indices": 8}},
        "../../checkpoints/tax3d-cd-official-simple/config.json": {"model": {}, "diffusion": {}, "data": {}, "train": {
            "steps": 900, "minutes": 30.0, "val_demos": 4, "val_samples": 2, "val_every": 300}},
    }


KINDS = {"fidelity.json": "fidelity", "expert_rates": "expert-rates", "sim_benchmark": "sim-benchmark",
         "official_val.json": "official-val", "official_training.json": "train-log",
         "model_benchmark": "model-benchmark", "predict_benchmark": "model-benchmark", "precision_benchmark": "model-benchmark", "fps_benchmark": "fps-benchmark",
         "ttq-": "study", "evals/": "eval", "unimodal-floor-20": "predict", "-samplers-": "predict"}


def kind_of(rel: str) -> str | None:
    """The kind of a fixture's kept JSON by its path (a run's config.json has none)."""
    return None if rel.endswith("config.json") else next(k for part, k in reversed(KINDS.items()) if part in rel)


@pytest.fixture
def measured(tmp_path: Path) -> Path:
    """docs/results/ with the paper's data file, the three measurement declarations and small kept JSON for them."""
    root = tmp_path / "docs" / "results"
    (root / "pages").mkdir(parents=True)
    shutil.copy(RESULTS / "paper.toml", root / "paper.toml")
    for name in ("hangproccloth-sim", "official-simple", "training"):
        shutil.copy(RESULTS / "pages" / f"{name}.toml", root / "pages" / f"{name}.toml")
    for rel, data in measurement_json().items():
        (root / rel).parent.mkdir(parents=True, exist_ok=True)
        kind = kind_of(rel)
        (root / rel).write_text(json.dumps(data if kind is None else stamp(kind, kept.KINDS[kind][0][-1], data)))
    (root / "training.md").write_text("# T\n\nbefore\n<!-- study -->\nold\n<!-- /study -->\nafter\n")
    (root.parent / "training.md").write_text("# G\n<!-- differences -->\nold\n<!-- /differences -->\nend\n")
    return root


def test_measurement_pages_from_fixture_json(measured):
    assert main(["--root", str(measured)]) == 0
    sim = (measured / "hangproccloth-sim.md").read_text()
    assert sim.startswith("# HangProcCloth simulation: fidelity, pseudo-expert, speed\n\nOur HangProcCloth-simple "
                          "scene starts where the official demonstrations start (initial cloth within 2.0e-05 of ")
    assert "| goal RMSE against the official goal (mean / median / max) | 0.250 / 0.200 / 0.750 |" in sim
    assert "| demos with goal RMSE under 0.5 | 1 | 1 |" in sim
    assert "| hangproccloth-simple | `unseen` | 4 | 0.75 | 1 |" in sim and "| hangbag | 640 | 8.50 | - |" in sim
    assert ("`python scripts/fidelity.py` (recorded with an earlier version; today: `python -m lab.studies.fidelity`) "
            "on fixture machine, 2026-02-03") in sim
    official = (measured / "official-simple.md").read_text()
    assert "TAX3D-CD predicts goals 0.125 RMSE from the official `val` goals, against the paper's 0.255" in official
    assert "| TAX3D-CD, this checkpoint, 10-step DDIM | 0.375 | 0.188 |" in official
    assert ("`tax3d train --preset cpu --out runs/o` on fixture machine, 2026-02-03 (log not committed" in official
            and "a 30-minute plan on one core beside another run, 900 steps" in official
            and "(0.250, best of 2 samples) on the first 4 official `val` demos, reached at step 600" in official)
    assert "(per sample: 0.125, 0.125)" in official
    assert "| speed-up, 10-step DDPM over 100-step | **10.0x** |" in official
    assert "| prediction of 20,000 action points, network on 256, 10-step DDPM | 0.25 s |" in official
    assert "| 0.250 / 0.200 (ratio **1.250**) |" in official and "on the 8 `val` cloths" in official
    training = (measured / "training.md").read_text()
    # the verdict names the recipe the preset took up, not the lowest RMSE of the study
    assert training.startswith("# T\n\nbefore\n<!-- study -->\n**The study's recipe, now the `cpu` preset "
                               "(`--opt v-grip16-all512-110min` on the preset of its time), with all `512` unimodal "
                               "training demos ends its 110-minute plan at validation RMSE 0.700** "
                               "(mean-goal floor 1.750;")
    assert "and hangs 0.875 / 0.85 of `unseen` / `ood` cloths (the paper's: 0.90 / 0.85)." in training
    assert training.endswith("<!-- /study -->\nafter\n") and "old" not in training
    row_a = next(line for line in training.splitlines() if line.startswith("| ttq-1 | a |"))
    # 15 min: the validation at 14; 30: at 29; 60: at 61 (within 10%); 120: the last, at 61; whole-run and
    # first-steps rates
    assert "| 2.000 (14 min) | 1.500 (29 min) | 0.900 (61 min) | 0.900 (61 min) | 0.900 (61 min) | 100 | 120 |" in row_a
    assert "![validation RMSE against minutes](training/time_to_quality.png)" in training
    assert "[training/ttq-1.json](training/ttq-1.json), [training/ttq-2.json](training/ttq-2.json)" \
        in training and training.count("on fixture machine, 2026-02-03") == 1  # one mention for one machine and day
    # the multimodal study stays out of the unimodal table (its JSON is not a ttq-*.json) but feeds its note
    assert "| ttq-11" not in training and "multimodal-ttq-11" not in training.split("**Half an hour")[0]
    assert ("on the first `400` of a set twice as large (`--num 512`, beginning with it; see \"What the runs on the "
            "largest sets saw\"). The larger set's run ends at 0.900 after 5,400 steps, where the other stood at 0.800 "
            "by step 5,000 (its plan, timed slower, ended after 54 minutes)") in training
    assert "The policy with their last weights hangs 0.625 / 0.675 and 0.55 / 0.55 of `unseen` / `ood` cloths" in training
    assert ("W = 16 and 128 end at validation RMSE 0.900 and 1.000 (unweighted: 0.700), grip error 0.450 and 0.500. "
            "With their best weights the policy hangs 0.875 / 0.75 and 0.75 / 0.75 of `unseen` / `ood` cloths, "
            "against 0.625 / 0.50 unweighted.") in training
    assert "grasped vertices lie 0.125 / 0.125 from the demonstration's (W = 16) against 0.375 / 0.375" in training
    assert "the larger set covers 1.050 against 1.050 after about 20 minutes" in training
    assert "hangs 0.50 / 0.25 of `unseen` / `ood` cloths, against 0.25 / 0.125 for the run it replaces" in training
    assert "planned for 30 minutes (`--train.minutes 30`, 3,000 steps), ends at validation RMSE 1.250" in training
    assert "runs at 0.50x the speed of the `float32` step (the paper's larger network: 1.50x)" in training
    assert "points on only 3 of 8 real cloth and bag clouds (the numpy loop: 8)" in training
    assert (measured / "training" / "time_to_quality.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    guide = (measured.parent / "training.md").read_text()
    assert guide.startswith("# G\n<!-- differences -->\n| `cpu` instead of `paper` |") and "old" not in guide
    assert ("| the `v` weighting of the loss (`paper`: the epsilon MSE) | 0.500 (60 min) / 0.550 (60 min) | - | "
            "ttq-4: v-loss; ttq-2: eps-subsets-ema |") in guide
    assert "| 0.65 / 0.65 against 0.60 / 0.55 | ttq-6: v-95min; ttq-7: v-rotate-95min |" in guide
    assert main(["--root", str(measured), "--check"]) == 0
    assert build(measured) == build(measured)  # the plot too


@pytest.mark.parametrize("rel, old, new, page", [
    ("fidelity.json", '"expert_success": 0.5', '"expert_success": 0.625', "hangproccloth-sim.md"),
    ("sim_benchmark.json", '"sim_steps_per_second": 640.0', '"sim_steps_per_second": 650.0', "hangproccloth-sim.md"),
    ("official_val.json", '"demos": 8', '"demos": 9', "official-simple.md"),
    ("predict_benchmark.json", '"speedup_10_vs_100": 10.0', '"speedup_10_vs_100": 9.0', "official-simple.md"),
    ("model_benchmark.json", '"seconds": 1.0', '"seconds": 2.0', "official-simple.md"),
    ("training/ttq-1.json", '"val_rmse": 0.7', '"val_rmse": 0.75', "training.md")])
def test_check_names_a_measurement_page_whose_json_changed(measured, capsys, rel, old, new, page):
    assert main(["--root", str(measured)]) == 0
    path = measured / rel
    text = path.read_text()
    assert old in text
    path.write_text(text.replace(old, new))
    capsys.readouterr()
    assert main(["--root", str(measured), "--check"]) == 1
    assert f"{page} differs" in capsys.readouterr().err


@pytest.mark.parametrize("rel", ["sim_benchmark_hangbag.json", "official_training.json", "model_benchmark.json",
                                 "predict_benchmark.json",
                                 "training/unimodal-floor-20.json", "training/ttq-5.json",
                                 "training/ttq-6.json"])
def test_missing_measurement_json_is_a_one_line_error(measured, capsys, rel):
    (measured / rel).unlink()
    err = one_line_error(capsys, ["--root", measured], main=main)
    assert rel.rsplit("/", 1)[-1].replace("ttq-1.json", "ttq-*.json") in err, err
    assert not (measured / "official-simple.md").exists() and "old" in (measured / "training.md").read_text()


def test_training_page_without_its_markers_is_a_one_line_error(measured, capsys):
    (measured / "training.md").write_text("# T\n")
    one_line_error(capsys, ["training", "--root", measured], "training.md: no <!-- study -->", main=main)


def test_the_readme_row_is_the_protocols_cd_once_it_is_run(root):
    """Before the table has a TAX3D-CD row the README shows the declared row; after, the protocol's, with intervals."""
    from tax3d.eval import ledger
    from tests.test_table import row, scored

    def readme_row() -> str:
        spec = declaration(root / "pages" / "fixture.toml")
        paper = tomllib.loads((root / "paper.toml").read_text())
        return TaskPage(root / "pages" / "fixture.toml", root, paper, spec).readme_row()

    assert "| Fixture | 0.75 / 0.75 (TAX3D-CD, cpu preset, fixture) | 0.90 / 0.85 |" in readme_row()
    for demos, success in ((64, 0.5), (512, 0.875)):
        folder = root / "table" / "hangproccloth-unimodal" / str(demos)
        folder.mkdir(parents=True)
        kept = {**row("cd", success), "num_train": demos}
        (folder / "cd.json").write_text(json.dumps(kept))
        ledger.append(root / "table" / "ledger.jsonl", scored(kept, demos))
    assert readme_row().startswith("| Fixture | 0.875 (0.74-0.95) / 0.875 (0.74-0.95) (TAX3D-CD, 512 demos, "
                                   "`--preset cpu`, 60-minute plan; weights chosen on `val`, test scored once) | "
                                   "0.90 / 0.85 |")


@pytest.fixture
def speed_root(tmp_path: Path) -> Path:
    """docs/results/ with the speed page's declaration and the kept JSON it reads."""
    root = tmp_path / "docs" / "results"
    (root / "pages").mkdir(parents=True)
    shutil.copy(RESULTS / "paper.toml", root / "paper.toml")
    spec = (RESULTS / "pages" / "training-speed.toml").read_text()
    (root / "pages" / "training-speed.toml").write_text(spec)
    for source in tomllib.loads(spec)["source"]:
        (root / source["summary"]).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy(RESULTS / source["summary"], root / source["summary"])
    return root


def test_speed_page_plots_the_named_pairs_curves(speed_root, capsys):
    assert main(["training-speed", "--root", str(speed_root)]) == 0
    spec = tomllib.loads((speed_root / "pages" / "training-speed.toml").read_text())
    drawn = plots.drawn_from((speed_root / "training-speed.png").read_bytes())
    pairs = {s["id"]: s for s in spec["source"]}
    expected = [f"{i}: {name}" for i in spec["plot"]
                for name in json.loads((speed_root / pairs[i]["summary"]).read_text())["runs"]]
    assert [run[0] for run in drawn["runs"]] == expected and len(expected) >= 2
    page = (speed_root / "training-speed.md").read_text()
    assert "![validation RMSE against training minutes](training-speed.png)" in page.split("## Where a step goes")[0]


def test_speed_page_plot_of_an_unknown_pair_is_a_one_line_error(speed_root, capsys):
    toml = speed_root / "pages" / "training-speed.toml"
    toml.write_text(re.sub(r'^plot = \[.*\]$', 'plot = ["nope"]', toml.read_text(), flags=re.M))
    one_line_error(capsys, ["training-speed", "--root", speed_root], "training-speed.toml: plot names nope",
                   main=main)
    assert not (speed_root / "training-speed.md").exists()


def test_speed_page_says_which_runs_validate_on_the_training_size_sample(speed_root):
    spec = tomllib.loads((speed_root / "pages" / "training-speed.toml").read_text())
    pair = next(s for s in spec["source"] if s.get("table") == "pair")
    path = speed_root / pair["summary"]
    kept = json.loads(path.read_text())
    name = list(kept["runs"])[-1]
    kept["runs"][name]["config"]["train"]["val_points"] = "sampled"
    path.write_text(json.dumps(kept))
    assert main(["training-speed", "--root", str(speed_root)]) == 0
    caption = next(line for line in (speed_root / "training-speed.md").read_text().splitlines()
                   if line.startswith(f"**{pair['label']}**"))
    assert f"; {name}: the network's input a farthest-point sample of its training size" in caption
    assert caption.count("farthest-point") == 1
