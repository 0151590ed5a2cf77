"""Kept JSON: the small files under docs/results/ that every number of a result page comes from.

Each file holds `kind` and `version` beside its values (tax3d.kept.stamp), written by the command that measured it
(KINDS names it); `load` reads a file of the kinds its reader expects and refuses any other kind or version in one
line. A run's configuration, kept as `tax3d train` wrote its config.json, has no kind of its own: `config` reads one.
"""

from __future__ import annotations

import json
from pathlib import Path

from tax3d.errors import UsageError

# kind: (the versions read, what writes it)
KINDS: dict[str, tuple[tuple[int, ...], str]] = {
    "eval": ((1,), "`tax3d eval` (OUT/summary.json)"),
    "train-log": ((1, 2), "`tax3d train` (OUT/summary.json)"),
    "val-curve": ((1,), "an earlier `tax3d train` log, kept by a script since replaced by OUT/summary.json"),
    "fixed-goal": ((1,), "an earlier fixed-goal policy, today `tax3d eval --goal demo` or `--goal mean`"),
    "train-run": ((1,), "a training run's figures, transcribed from its log"),
    "predict": ((1,), "`tax3d predict --summary`"),
    "table-row": ((1,), "`tax3d table --keep`"),
    "study": ((1,), "`python -m lab.studies.time_to_quality`"),
    "paper-count": ((1,), "`python -m lab.studies.paper_count`"),
    "samplers": ((1,), "`python -m lab.studies.samplers`"),
    "val-points": ((1,), "`python -m lab.studies.val_points`"),
    "sampler-check": ((1,), "an earlier sampler comparison, today `python -m lab.studies.samplers`"),
    "precision-parts": ((1,), "an earlier one-off study of where multimodal samples miss"),
    "success-by-rmse": ((1,), "`python -m lab.studies.success_by_rmse`"),
    "expert-rates": ((1,), "`python -m lab.studies.expert_rates`"),
    "fidelity": ((1,), "`python -m lab.studies.fidelity`"),
    "official-val": ((1,), "`python -m lab.studies.official_report`"),
    "goal-spread": ((1,), "`python -m lab.studies.goal_spread`"),
    "mode-spread": ((1,), "`python -m lab.studies.mode_spread`"),
    "paper-budget": ((1,), "`python benchmarks/paper_budget_run.py`"),
    "sim-benchmark": ((1,), "`python benchmarks/sim.py`"),
    "eval-benchmark": ((1,), "`python benchmarks/eval.py`"),
    "model-benchmark": ((1,), "`python benchmarks/model.py`"),
    "fps-benchmark": ((1,), "`python benchmarks/fps.py`"),
    "parallel-benchmark": ((1,), "`python benchmarks/parallel.py`"),
    "train-step-benchmark": ((1,), "`python benchmarks/train_step.py`"),
    "train-ddp-benchmark": ((1,), "`python benchmarks/train_ddp.py`"),
}
CONFIG_SECTIONS = ("model", "diffusion", "data", "train")


def _json(path: Path, expected: str) -> dict:
    if not path.is_file():
        raise UsageError(f"{path}: not found; expected {expected}")
    try:
        data = json.loads(path.read_text())
    except ValueError as err:
        raise UsageError(f"{path}: not valid JSON ({err}); expected {expected}") from None
    if not isinstance(data, dict):
        raise UsageError(f"{path}: a JSON {type(data).__name__}; expected {expected}")
    return data


def read(path: Path, kinds: tuple[str, ...] = ()) -> dict:
    """The file as written, after checking that its kind is one of `kinds` (any known kind where empty) and its
    version one that is read."""
    allowed = kinds or tuple(KINDS)
    expected = "a kept JSON of kind " + " or ".join(repr(k) for k in allowed)
    data = _json(path, expected)
    kind, version = data.get("kind"), data.get("version")
    if kind not in allowed:
        raise UsageError(f"{path}: kind {kind!r}; expected {expected}")
    versions, writer = KINDS[kind]
    if version not in versions:
        raise UsageError(f"{path}: {kind!r} of version {version!r}; expected version "
                         f"{' or '.join(map(str, versions))}, as {writer} writes it")
    return data


def load(path: Path, kinds: tuple[str, ...] = ()) -> dict:
    """What a page reads of a kept file: an evaluation's summary, a validation curve or a table row with its best and
    last validation, any other kind as written."""
    data = read(path, kinds)
    if data["kind"] == "eval":
        return data["summary"]
    if data["kind"] == "train-log" and data["version"] >= 2:
        data = {**data, "points": curve(data["records"])}
    points = data.get("validations") if data["kind"] == "table-row" else data.get("points")
    if data["kind"] not in ("val-curve", "train-log", "table-row") or not points:  # floor and ceiling rows train nothing
        return data
    best, last = min(points, key=lambda p: p["val_rmse"]), points[-1]
    return {**data, "best_step": best["step"], "best_rmse": best["val_rmse"], "last_step": last["step"],
            "last_rmse": last["val_rmse"]}


def curve(records: list[dict]) -> list[dict]:
    """The validated steps of a `tax3d train` log: step, validation RMSE (best and mean of the samples, coverage and
    grip error where logged) and minutes."""
    optional = ("val_coverage_rmse", "val_grip_error")
    return [{"step": r["step"], "val_rmse": r["val_rmse"], "val_rmse_mean": r.get("val_rmse_mean"),
             **{k: r[k] for k in optional if k in r}, "minutes": round(r["seconds"] / 60, 1)}
            for r in records if "val_rmse" in r]


def config(path: Path) -> dict:
    """A kept `tax3d train` config.json."""
    data = _json(path, "a `tax3d train` config.json")
    missing = [k for k in CONFIG_SECTIONS if k not in data]
    if missing:
        raise UsageError(f"{path}: no {', '.join(missing)} section; expected a `tax3d train` config.json")
    return data
