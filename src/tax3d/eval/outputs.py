"""What an evaluation writes to OUT: results.json (the summary and every episode), summary.json (kept JSON of kind
"eval", tax3d.kept: the summary alone) and, where asked, the report."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from tax3d import kept
from tax3d.atomic import write_text
from tax3d.eval.report import write_report


def write_outputs(out: Path, summary: dict, results: list[dict], report_title: str | None = None) -> None:
    """results.json and summary.json in OUT, and the report titled `report_title` (None: no report)."""
    out.mkdir(parents=True, exist_ok=True)
    scalars = [{k: v for k, v in r.items() if not isinstance(v, np.ndarray) and k not in ("cloth_key",)}
               for r in results]
    write_text(out / "results.json", json.dumps({"summary": summary, "episodes": scalars}, indent=2, default=_plain))
    write_text(out / "summary.json", json.dumps(kept.stamp("eval", 1, {"summary": summary}), indent=1,
                                                default=_plain) + "\n")
    if report_title is not None:
        episodes = [r for r in results if r["action_pc"] is not None]
        write_report(out, summary, episodes, title=report_title)


def _plain(value):
    if isinstance(value, (np.generic,)):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    raise TypeError(f"cannot serialise {type(value)}")
