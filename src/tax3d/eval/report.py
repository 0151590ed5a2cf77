"""Evaluation report: an HTML page with the results table and interactive 3D goals, PNG pictures, a markdown table."""

from __future__ import annotations

import html
import io
import math
import re
from pathlib import Path

import numpy as np

from tax3d.atomic import write_bytes

ANCHOR_COLOR = "#8c8c8c"
ACTION_COLOR = "#1f77b4"
TRUE_GOAL_COLOR = "#2ca02c"
GOAL_COLORS = ((255, 159, 28), (193, 18, 31))  # first and last predicted sample: orange to red
MAX_SAMPLES_SHOWN = 8
MAX_ANIMATION_FRAMES = 60
PROVENANCE_KEYS = ("checkpoint", "task", "variant", "command", "machine", "date")
DASH = "\u2014"


# ---------------------------------------------------------------- small helpers


def _finite(points) -> np.ndarray:
    """(P,3) float32 array without rows holding NaN or inf; empty (0,3) for None."""
    if points is None:
        return np.zeros((0, 3), np.float32)
    points = np.asarray(points, dtype=np.float32).reshape(-1, 3)
    return points[np.isfinite(points).all(axis=1)]


def _goal_samples(pred_goal) -> np.ndarray:
    """Predicted goals as (S,N,3), accepting a single (N,3) cloud."""
    if pred_goal is None:
        return np.zeros((0, 0, 3), np.float32)
    pred_goal = np.asarray(pred_goal, dtype=np.float32)
    return pred_goal[None] if pred_goal.ndim == 2 else pred_goal


def _goal_color(i: int, count: int) -> str:
    t = i / max(count - 1, 1)
    rgb = [round(a + t * (b - a)) for a, b in zip(*GOAL_COLORS)]
    return "rgb({},{},{})".format(*rgb)


def _number(value, digits: int) -> str:
    if value is None:
        return DASH
    return f"{float(value):.{digits}f}"




def _safe_name(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", str(text)).strip("._") or "episode"


def _split_order(summary: dict, episodes: list[dict]) -> list[str]:
    order = list(summary.get("splits", {}))
    for episode in episodes:
        if episode["split"] not in order:
            order.append(episode["split"])
    return order


# ---------------------------------------------------------------- results table


def _table_rows(summary: dict) -> tuple[list[str], list[tuple[str, list[str]]]]:
    """Split names and (label, cells) rows in the paper's layout: metrics down, splits across."""
    splits = summary.get("splits", {})
    names = list(splits)
    rows = [("RMSE (\u2193)", [_number(splits[s].get("rmse"), 3) for s in names]),
            ("Success rate (\u2191)", [_number(splits[s].get("success_rate"), 2) for s in names])]
    for key, label in (("coverage_rmse", "Coverage RMSE (\u2193)"), ("precision_rmse", "Precision RMSE (\u2193)")):
        if any(splits[s].get(key) is not None for s in names):
            rows.append((label, [_number(splits[s].get(key), 3) for s in names]))
    rows.append(("Episodes", [str(splits[s].get("episodes", DASH)) for s in names]))
    rows.append(("Prediction time (s)", [_number(splits[s].get("predict_seconds"), 1) for s in names]))
    rows.append(("Simulation time (s)", [_number(splits[s].get("sim_seconds"), 1) for s in names]))
    return names, rows


def _md_code(text: str) -> str:
    text = str(text).replace("\n", " ")
    fence = "``" if "`" in text else "`"
    return f"{fence} {text} {fence}" if fence == "``" else f"`{text}`"


def results_markdown(summary: dict, title: str = "TAX3D evaluation") -> str:
    lines = [f"# {title}", ""]
    for key in PROVENANCE_KEYS:
        if summary.get(key) is not None:
            lines.append(f"- {key.capitalize()}: {_md_code(summary[key])}")
    names, rows = _table_rows(summary)
    lines += ["", "| | " + " | ".join(n.replace("|", "\\|") for n in names) + " |",
              "|---|" + "---:|" * len(names)]
    lines += [f"| {label} | " + " | ".join(cells) + " |" for label, cells in rows]
    return "\n".join(lines) + "\n"


NO_TRUE_GOAL = ("These anchor poses are fresh: no demonstration was made on them, so there is no true goal to "
                "show and RMSE, which measures the predicted goal against it, is not defined (-).")


def _results_html(summary: dict) -> str:
    names, rows = _table_rows(summary)
    head = "".join(f"<th>{html.escape(n)}</th>" for n in names)
    body = "".join(
        f"<tr><th>{html.escape(label)}</th>" + "".join(f"<td>{html.escape(c)}</td>" for c in cells) + "</tr>"
        for label, cells in rows)
    table = f'<table class="results"><thead><tr><th></th>{head}</tr></thead><tbody>{body}</tbody></table>'
    splits = summary.get("splits", {})
    if splits and all(s.get("rmse") is None for s in splits.values()):
        table += f"<p>{NO_TRUE_GOAL}</p>"
    return table


def _provenance_html(summary: dict) -> str:
    parts = [f"<b>{key}</b>: <code>{html.escape(str(summary[key]))}</code>"
             for key in PROVENANCE_KEYS if summary.get(key) is not None]
    return '<p class="provenance">' + " &middot; ".join(parts) + "</p>"


# ---------------------------------------------------------------- matplotlib pictures


def _new_figure(width_px: int, height_px: int, dpi: int = 100):
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(width_px / dpi, height_px / dpi), dpi=dpi)
    FigureCanvasAgg(fig)
    return fig


def _cube_limits(ax, clouds: list[np.ndarray], margin: float = 0.05, zoom: float = 1.0) -> None:
    """Equal axis ranges around all the points, so that the cloth is not distorted."""
    every = np.concatenate([c for c in clouds if len(c)] or [np.zeros((1, 3), np.float32)])
    low, high = every.min(0), every.max(0)
    centre, half = (low + high) / 2, max(float((high - low).max()) / 2, 0.5) * (1 + margin)
    ax.set_xlim(centre[0] - half, centre[0] + half)
    ax.set_ylim(centre[1] - half, centre[1] + half)
    ax.set_zlim(centre[2] - half, centre[2] + half)
    ax.set_box_aspect((1, 1, 1), zoom=zoom)


def _scatter(ax, points: np.ndarray, color, size: float, label: str | None = None, alpha: float = 1.0,
             absent: bool = False) -> None:
    """Points with a legend entry; a cloud that is absent (no true goal on a fresh pose) gets no entry."""
    if len(points):
        ax.scatter(*points.T, s=size, c=[color], label=label, alpha=alpha, depthshade=False, linewidths=0)
    elif label and not absent:  # keep the legend entry even when every point was dropped
        ax.scatter([], [], [], s=size, c=[color], label=label)


def _style_axes(ax, title: str, fontsize: float = 8) -> None:
    ax.set_title(title, fontsize=fontsize)
    ax.view_init(elev=18, azim=-60)
    ax.tick_params(labelsize=5, pad=0)
    ax.set_xlabel("x", fontsize=6, labelpad=-8)
    ax.set_ylabel("y", fontsize=6, labelpad=-8)
    ax.set_zlabel("z", fontsize=6, labelpad=-8)


def _save_png(fig, path: Path) -> Path:
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png")
    return write_bytes(path, buffer.getvalue())


def _episode_label(episode: dict) -> str:
    verdict = "exploded" if episode.get("exploded") else "success" if episode.get("success") else "failure"
    return f"{episode['split']} / {episode['name']}: {verdict}"


def released_png(path: Path, episode: dict) -> Path:
    """Anchor and cloth after release (true goal faint when known), about 400x300 px."""
    fig = _new_figure(400, 300)
    ax = fig.add_subplot(projection="3d")
    anchor, released, true_goal = (_finite(episode.get(k)) for k in ("anchor_pc", "released_pc", "true_goal"))
    _scatter(ax, anchor, ANCHOR_COLOR, 1.5, "anchor")
    if len(true_goal):
        _scatter(ax, true_goal, TRUE_GOAL_COLOR, 1.5, "true goal", alpha=0.25,
                 absent=episode.get("true_goal") is None)
    _scatter(ax, released, ACTION_COLOR, 2.5, "cloth after release")
    _cube_limits(ax, [anchor, released, true_goal], zoom=1.1)
    _style_axes(ax, _episode_label(episode))
    ax.legend(loc="upper left", fontsize=6, markerscale=3, frameon=False)
    fig.subplots_adjust(left=0, right=1, bottom=0.02, top=0.92)
    return _save_png(fig, path)


def _overview_choice(episodes: list[dict], splits: list[str], count: int = 4) -> list[dict]:
    """Up to `count` episodes: a success and a failure per split where there are, alternating which comes first."""
    per_split = []
    for i, split in enumerate(splits):
        mine = [e for e in episodes if e["split"] == split]
        success = next((e for e in mine if e.get("success")), None)
        failure = next((e for e in mine if not e.get("success") and not e.get("exploded")), None)
        failure = failure or next((e for e in mine if not e.get("success")), None)
        pair = [success, failure] if i % 2 == 0 else [failure, success]
        per_split.append([e for e in pair if e is not None])
    chosen = [group[k] for k in range(2) for group in per_split if len(group) > k]
    return chosen[:count]


def overview_png(path: Path, episodes: list[dict], splits: list[str]) -> Path:
    """A grid of up to four episodes: anchor, initial action, first predicted goal, true goal."""
    chosen = _overview_choice(episodes, splits)
    cols = min(2, max(len(chosen), 1))
    rows = max(1, math.ceil(len(chosen) / cols))
    fig = _new_figure(460 * cols, 400 * rows + 40)
    for i, episode in enumerate(chosen):
        ax = fig.add_subplot(rows, cols, i + 1, projection="3d")
        anchor, action, true_goal = (_finite(episode.get(k)) for k in ("anchor_pc", "action_pc", "true_goal"))
        samples = _goal_samples(episode.get("pred_goal"))
        goal = _finite(samples[0]) if len(samples) else _finite(None)
        _scatter(ax, anchor, ANCHOR_COLOR, 1.5, "anchor")
        _scatter(ax, action, ACTION_COLOR, 2.5, "action (initial cloth)")
        _scatter(ax, true_goal, TRUE_GOAL_COLOR, 2.5, "true goal", absent=episode.get("true_goal") is None)
        _scatter(ax, goal, _rgb01(GOAL_COLORS[0]), 2.5, "predicted goal")
        _cube_limits(ax, [anchor, action, goal, true_goal], zoom=1.08)
        _style_axes(ax, _episode_label(episode), fontsize=10)
    if not chosen:
        fig.text(0.5, 0.5, "no episodes", ha="center", va="center")
    else:
        handles, labels = fig.axes[0].get_legend_handles_labels()
        fig.legend(handles, labels, loc="lower center", ncol=4, fontsize=9, markerscale=4, frameon=False)
    fig.subplots_adjust(left=0, right=1, bottom=40 / (400 * rows + 40) + 0.02, top=0.95, wspace=0.02, hspace=0.14)
    return _save_png(fig, path)


def _rgb01(rgb) -> tuple[float, float, float]:
    return tuple(c / 255 for c in rgb)


def _frame_indices(count: int, max_frames: int) -> list[int]:
    if count <= max_frames:
        return list(range(count))
    return sorted(set(np.linspace(0, count - 1, max_frames).round().astype(int).tolist()))


# ---------------------------------------------------------------- plotly figures


def _trace(points: np.ndarray, name: str, color: str, size: float, opacity: float = 1.0, **kwargs):
    import plotly.graph_objects as go

    return go.Scatter3d(x=points[:, 0], y=points[:, 1], z=points[:, 2], mode="markers", name=name,
                        marker=dict(size=size, color=color, opacity=opacity, line=dict(width=0)), **kwargs)


def _grip_points(samples: np.ndarray, grip_vertices) -> np.ndarray:
    if not len(samples) or grip_vertices is None:
        return _finite(None)
    index = [int(v) for v in grip_vertices if 0 <= int(v) < samples.shape[1]]
    return _finite(samples[0][index])


def episode_figure(episode: dict):
    """Interactive 3D scatter: anchor grey, action blue, predicted goal samples orange to red, true goal green."""
    import plotly.graph_objects as go

    samples = _goal_samples(episode.get("pred_goal"))
    shown = samples[:MAX_SAMPLES_SHOWN]
    traces = [_trace(_finite(episode.get("anchor_pc")), "anchor", ANCHOR_COLOR, 1.5),
              _trace(_finite(episode.get("action_pc")), "action (initial)", ACTION_COLOR, 2)]
    for i, goal in enumerate(shown):
        traces.append(_trace(_finite(goal), f"predicted goal {i + 1}", _goal_color(i, len(shown)), 2))
    if episode.get("true_goal") is not None:
        traces.append(_trace(_finite(episode["true_goal"]), "true goal", TRUE_GOAL_COLOR, 2, opacity=0.7))
    grips = _grip_points(samples, episode.get("grip_vertices"))
    if len(grips):
        traces.append(_trace(grips, "grip vertices (goal 1)", "black", 6))
    fig = go.Figure(traces)
    fig.update_layout(height=440, margin=dict(l=0, r=0, t=10, b=0), scene=dict(aspectmode="data"),
                      legend=dict(itemsizing="constant", font=dict(size=10)), uirevision=True)
    return fig


def denoising_figure(frames: np.ndarray, anchor: np.ndarray):
    """Plotly animation of the predicted goal over the denoising steps, with a slider and a play button."""
    import plotly.graph_objects as go

    frames = np.asarray(frames, dtype=np.float32)
    keep = _frame_indices(len(frames), MAX_ANIMATION_FRAMES)
    clouds = [_finite(frames[k]) for k in keep]
    first = clouds[0] if clouds else _finite(None)
    anchor = _finite(anchor)
    goal_color = _goal_color(1, 1)
    fig = go.Figure(
        [_trace(anchor, "anchor", ANCHOR_COLOR, 1.5), _trace(first, "predicted goal", goal_color, 2)],
        frames=[go.Frame(data=[_trace(c, "predicted goal", goal_color, 2)], traces=[1], name=str(k))
                for k, c in zip(keep, clouds)])
    step = dict(mode="immediate", frame=dict(duration=0, redraw=True), transition=dict(duration=0))
    fig.update_layout(
        height=520, margin=dict(l=0, r=0, t=10, b=0), scene=_fixed_scene([anchor, *clouds]),
        updatemenus=[dict(type="buttons", x=0.02, y=0.02, xanchor="left", yanchor="bottom", buttons=[
            dict(label="Play", method="animate",
                 args=[None, dict(step, frame=dict(duration=150, redraw=True), fromcurrent=True)]),
            dict(label="Pause", method="animate", args=[[None], step])])],
        sliders=[dict(x=0.15, len=0.85, y=0.02, currentvalue=dict(prefix="step "), steps=[
            dict(label=str(k + 1), method="animate", args=[[str(k)], step]) for k in keep])])
    return fig


def _fixed_scene(clouds: list[np.ndarray]) -> dict:
    """Axis ranges that hold every frame, in equal proportions, so that the view stays still while playing."""
    every = np.concatenate([c for c in clouds if len(c)] or [np.zeros((1, 3), np.float32)])
    low, high = every.min(0), every.max(0)
    pad = 0.05 * max(float((high - low).max()), 1.0)
    low, high = low - pad, high + pad
    scene = {f"{a}axis": dict(range=[float(low[i]), float(high[i])], autorange=False) for i, a in enumerate("xyz")}
    ratio = (high - low) / (high - low).max()
    return dict(scene, aspectmode="manual", aspectratio=dict(x=float(ratio[0]), y=float(ratio[1]), z=float(ratio[2])))


def _figure_html(fig) -> str:
    # responsive: the figure takes its box's width (the released-cloth picture beside it keeps its own)
    return fig.to_html(full_html=False, include_plotlyjs=False, config=dict(displaylogo=False, responsive=True))


# ---------------------------------------------------------------- the page

STYLE = """
body { font-family: system-ui, sans-serif; margin: 1.5em auto; max-width: 1250px; color: #222; }
table { border-collapse: collapse; margin: 0.6em 0 1.2em; }
th, td { border: 1px solid #ccc; padding: 0.25em 0.7em; text-align: right; }
th:first-child { text-align: left; }
.provenance { color: #555; font-size: 0.9em; line-height: 1.6; }
.episode { border-top: 1px solid #ddd; padding: 0.4em 0 0.8em; }
.episode-row { display: flex; gap: 1em; align-items: center; }
.episode-row > .figure { flex: 1 1 0; min-width: 0; overflow: hidden; }
.episode-row > img, .episode-row > p { flex: 0 0 auto; }
.success { color: #1a7f37; font-weight: bold; }
.failure { color: #c1121f; font-weight: bold; }
"""


def _verdict(episode: dict) -> tuple[str, str]:
    if episode.get("exploded"):
        return "failure (exploded)", "failure"
    return ("success", "success") if episode.get("success") else ("failure", "failure")


def _pick_figures(episodes: list[dict], splits: list[str], max_figures: int) -> dict[str, list[int]]:
    """Episode indices given a 3D figure, per split: shared round-robin over the splits, failures first."""
    queues = {}
    for split in splits:
        mine = [i for i, e in enumerate(episodes) if e["split"] == split and not e.get("exploded")]
        failures = [i for i in mine if not episodes[i].get("success")]
        queues[split] = failures + [i for i in mine if i not in failures]
    chosen = {split: [] for split in splits}
    left = max(int(max_figures), 0)
    while left and any(queues.values()):
        for split in splits:
            if queues[split] and left:
                chosen[split].append(queues[split].pop(0))
                left -= 1
    return chosen


def _image_names(episodes: list[dict]) -> dict[int, str]:
    """File names (under images/) of the released-cloth pictures, one per episode that has a released cloud."""
    names, used = {}, set()
    for i, episode in enumerate(episodes):
        if episode.get("exploded") or episode.get("released_pc") is None:
            continue
        stem = f"{_safe_name(episode['split'])}_{_safe_name(episode['name'])}_released"
        name, k = f"{stem}.png", 2
        while name in used:
            name, k = f"{stem}_{k}.png", k + 1
        used.add(name)
        names[i] = name
    return names


def _episode_card(episode: dict, image: str | None) -> str:
    text, css = _verdict(episode)
    samples = _goal_samples(episode.get("pred_goal"))
    shown = str(len(samples))
    if len(samples) > MAX_SAMPLES_SHOWN:
        shown = f"{MAX_SAMPLES_SHOWN} of {len(samples)}"
    picture = (f'<img src="images/{html.escape(image)}" alt="{html.escape(str(episode["name"]))} after release" '
               f'width="400" height="300">' if image else "<p>no picture of the released cloth</p>")
    return (f'<div class="episode"><h4>{html.escape(str(episode["name"]))}: '
            f'<span class="{css}">{html.escape(text)}</span></h4>'
            f'<p>RMSE: {_number(episode.get("rmse"), 3)} &middot; predicted goal samples shown: {shown}</p>'
            f'<div class="episode-row"><div class="figure">{_figure_html(episode_figure(episode))}</div>'
            f"{picture}</div></div>")


def _remaining_table(episodes: list[dict], indices: list[int], images: dict[int, str]) -> str:
    rows = []
    for i in indices:
        text, css = _verdict(episodes[i])
        link = f'<a href="images/{html.escape(images[i])}">picture</a>' if i in images else DASH
        rows.append(f"<tr><td>{html.escape(str(episodes[i]['name']))}</td><td class=\"{css}\">{html.escape(text)}</td>"
                    f"<td>{_number(episodes[i].get('rmse'), 3)}</td><td>{link}</td></tr>")
    return ('<table class="episodes"><thead><tr><th>Episode</th><th>Result</th><th>RMSE</th><th>After release</th>'
            f"</tr></thead><tbody>{''.join(rows)}</tbody></table>")


def _split_section(split: str, episodes: list[dict], figures: list[int], images: dict[int, str]) -> str:
    mine = [i for i, e in enumerate(episodes) if e["split"] == split]
    parts = [f"<h3>{html.escape(str(split))}</h3>"]
    parts += [_episode_card(episodes[i], images.get(i)) for i in figures]
    rest = [i for i in mine if i not in figures]
    if rest:
        parts.append(f"<h4>Other episodes ({len(rest)})</h4>" + _remaining_table(episodes, rest, images))
    if not mine:
        parts.append("<p>No episodes.</p>")
    return "\n".join(parts)


def _denoising_section(episodes: list[dict]) -> str:
    episode = next((e for e in episodes if e.get("denoising") is not None and len(e["denoising"])), None)
    if episode is None:
        return ""
    fig = denoising_figure(episode["denoising"], episode.get("anchor_pc"))
    return (f"<h2>Denoising: {html.escape(str(episode['split']))} / {html.escape(str(episode['name']))}</h2>"
            "<p>The predicted goal from noise to the final cloud, one frame per denoising step.</p>"
            + _figure_html(fig))


def report_html(summary: dict, episodes: list[dict], title: str, figures: dict[str, list[int]],
                images: dict[int, str]) -> str:
    import plotly.offline

    splits = _split_order(summary, episodes)
    true_goals = any(e.get("true_goal") is not None for e in episodes)
    body = [f"<h1>{html.escape(title)}</h1>", _provenance_html(summary), "<h2>Results</h2>", _results_html(summary),
            "<h2>Episodes</h2>", '<p>Anchor grey, action (initial cloth) blue, predicted goal samples orange to red, '
            + ("true goal green; " if true_goals else "") + 'the two grip vertices of the first sample in black. '
            'Failures are shown first.</p>']
    body += [_split_section(split, episodes, figures.get(split, []), images) for split in splits]
    if not episodes:
        body.append("<p>No episodes.</p>")
    body.append(_denoising_section(episodes))
    page = "\n".join(body)
    bundle = ""
    if "plotly-graph-div" in page:  # plotly.js once, in the head, for every figure below
        bundle = f'<script type="text/javascript">{plotly.offline.get_plotlyjs()}</script>'
    return (f'<!DOCTYPE html>\n<html lang="en">\n<head>\n<meta charset="utf-8">\n<title>{html.escape(title)}</title>\n'
            f"<style>{STYLE}</style>\n{bundle}\n</head>\n<body>\n{page}\n</body>\n</html>\n")


def write_report(out_dir: Path, summary: dict, episodes: list[dict], title: str = "TAX3D evaluation",
                 max_figures: int = 12) -> Path:
    """Write report.html, results.md and images/ (released cloths, overview) into out_dir; return report.html."""
    out_dir = Path(out_dir)
    image_dir = out_dir / "images"
    image_dir.mkdir(parents=True, exist_ok=True)
    splits = _split_order(summary, episodes)
    images = _image_names(episodes)
    for i, name in images.items():
        released_png(image_dir / name, episodes[i])
    overview_png(image_dir / "overview.png", episodes, splits)
    write_bytes(out_dir / "results.md", results_markdown(summary, html.escape(title, quote=False)).encode())
    figures = _pick_figures(episodes, splits, max_figures)
    page = report_html(summary, episodes, title, figures, images)
    return write_bytes(out_dir / "report.html", page.encode("utf-8"))
