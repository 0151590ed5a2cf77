"""The plots of the result pages, each drawn from a small JSON of what it shows, which the PNG carries in a text chunk
(`Source`): `python -m lab.results --check` compares a plot by that, not by its pixels, which change with matplotlib's
version."""

from __future__ import annotations

import io
import json
import struct

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
KEY = "Source"


def _png(fig, source: dict) -> bytes:
    out = io.BytesIO()
    fig.savefig(out, dpi=110, format="png", metadata={"Software": None, KEY: json.dumps(source, sort_keys=True)})
    return out.getvalue()


def drawn_from(png: bytes) -> dict | None:
    """The JSON a plot was drawn from (its `Source` text chunk), or None for a PNG without one."""
    if not png.startswith(PNG_SIGNATURE):
        return None
    at = len(PNG_SIGNATURE)
    while at + 8 <= len(png):
        length, kind = struct.unpack(">I4s", png[at:at + 8])
        body = png[at + 8:at + 8 + length]
        if kind == b"tEXt" and body.startswith(KEY.encode() + b"\0"):
            return json.loads(body[len(KEY) + 1:].decode("latin-1"))
        if kind == b"IEND":
            break
        at += 12 + length
    return None


def _figure(width: float, height: float):
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(width, height))
    FigureCanvasAgg(fig)
    return fig


def success_bars(labels: list[str], splits: tuple[str, ...], success: list[list[float | None]]) -> bytes:
    """Grouped bars of success per split, one group per row (a missing split drawn as 0)."""
    source = {"plot": "success-bars", "version": 1, "labels": labels, "splits": list(splits), "success": success}
    fig = _figure(max(6.0, 0.8 * len(labels) + 2), 4.8)
    ax = fig.add_subplot()
    width = 0.27
    for j, split in enumerate(splits):
        values = [0.0 if row[j] is None else row[j] for row in success]
        ax.bar([i + (j - 1) * width for i in range(len(labels))], values, width, label=split)
    ax.set_xticks(range(len(labels)), labels, rotation=30, ha="right", fontsize=7)
    ax.set_ylim(0, 1.22)
    ax.set_ylabel("success rate")
    ax.legend(fontsize=7, ncols=3, loc="upper center")
    fig.tight_layout()
    return _png(fig, source)


def validation_curves(runs: list[tuple[str, list[float], list[float]]], floor: float | None, ylabel: str) -> bytes:
    """Validation RMSE against training minutes, one line a run (label, minutes, RMSE), the mean-goal floor dashed."""
    import matplotlib

    source = {"plot": "validation-curves", "version": 1, "runs": [list(r) for r in runs], "floor": floor,
              "ylabel": ylabel}
    fig = _figure(8.4, 3.8)
    ax = fig.add_subplot()
    colors = matplotlib.colormaps["tab20"].colors  # one colour a run, up to twenty runs
    for k, (label, minutes, rmse) in enumerate(runs):
        ax.plot(minutes, rmse, marker="o", markersize=4, color=colors[k % len(colors)], label=label)
    if floor is not None:
        ax.axhline(floor, color="grey", linestyle="--", label="mean-goal floor")
    ax.set_xlabel("training minutes (one core each)")
    ax.set_ylabel(ylabel)
    ax.set_ylim(bottom=0)
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    ax.grid(alpha=0.3)
    fig.tight_layout()
    return _png(fig, source)


def sample_curves(runs: list[tuple[str, list[float], list[float]]], marks: list[tuple[str, float]],
                  floor: float | None, ylabel: str) -> bytes:
    """Validation RMSE against training samples seen (log scale), one line a run (label, samples, RMSE), each mark
    (label, samples) a vertical line, the mean-goal floor dashed."""
    source = {"plot": "sample-curves", "version": 1, "runs": [list(r) for r in runs], "marks": [list(m) for m in marks],
              "floor": floor, "ylabel": ylabel}
    fig = _figure(8.4, 3.8)
    ax = fig.add_subplot()
    for label, samples, rmse in runs:
        ax.plot(samples, rmse, marker="o", markersize=3, label=label)
    for k, (label, samples) in enumerate(marks):
        ax.axvline(samples, color="black" if k else "grey", linestyle=":", label=label)
    if floor is not None:
        ax.axhline(floor, color="grey", linestyle="--", label="mean-goal floor")
    ax.set_xscale("log")
    ax.set_xlabel("training samples seen (steps x batch)")
    ax.set_ylabel(ylabel)
    ax.set_ylim(bottom=0)
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    ax.grid(alpha=0.3, which="both")
    fig.tight_layout()
    return _png(fig, source)
