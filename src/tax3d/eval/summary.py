"""An evaluation's summary per split (success, RMSE, coverage and precision, appendix C) and its text table."""

from __future__ import annotations

import numpy as np

from tax3d.metrics import coverage_rmse, precision_rmse, success_interval


def summarise(results: list[dict], splits: list[str]) -> dict:
    """Per split: success rate, RMSE, and coverage / precision RMSE over each cloth's goals (appendix C)."""
    table = {}
    for split in splits:
        rows = [r for r in results if r["split"] == split]
        if not rows:
            continue
        scored = [r["rmse"] for r in rows if r["rmse"] is not None]
        executed = [r["executed_rmse"] for r in rows if r.get("executed_rmse") is not None]
        grips = [r["executed_grip_error"] for r in rows if r.get("executed_grip_error") is not None]
        clothes: dict[str, list[dict]] = {}
        for r in rows:
            if r["true_goal"] is not None and r["pred_goal"] is not None:
                clothes.setdefault(r["cloth_key"], []).append(r)
        coverage, precision = [], []
        for group in clothes.values():
            samples = np.concatenate([r["pred_goal"] for r in group])
            goals = np.stack([r["true_goal"] for r in group])
            coverage.append(float(coverage_rmse(samples, goals)))
            precision.append(float(precision_rmse(samples, goals)))
        table[split] = {
            "episodes": len(rows),
            "success_rate": float(np.mean([r["success"] for r in rows])),
            "success_ci95": list(success_interval(sum(bool(r["success"]) for r in rows), len(rows))),
            "rmse": float(np.mean(scored)) if scored else None,
            "executed_rmse": float(np.mean(executed)) if executed else None,
            "executed_grip_error": float(np.mean(grips)) if grips else None,
            "coverage_rmse": float(np.mean(coverage)) if coverage else None,
            "precision_rmse": float(np.mean(precision)) if precision else None,
            "predict_seconds": float(np.mean([r["predict_seconds"] for r in rows])),
            "sim_seconds": float(np.mean([r["sim_seconds"] for r in rows])),
            "failed_runs": sum(1 for r in rows if r.get("error") or r["exploded"]),
        }
    return table


def format_table(table: dict) -> str:
    splits = list(table)
    lines = [f"{'':<14}" + "".join(f"{s:>10}" for s in splits)]
    for label, key, fmt in (("RMSE", "rmse", "{:.3f}"), ("Success rate", "success_rate", "{:.2f}"),
                            ("Coverage RMSE", "coverage_rmse", "{:.3f}"), ("Precision RMSE", "precision_rmse", "{:.3f}")):
        if key != "success_rate" and key != "rmse" and all(table[s][key] is None for s in splits):
            continue
        cells = ["-" if table[s][key] is None else fmt.format(table[s][key]) for s in splits]
        lines.append(f"{label:<14}" + "".join(f"{c:>10}" for c in cells))
    return "\n".join(lines)
