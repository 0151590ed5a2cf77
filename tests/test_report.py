import re
from html.parser import HTMLParser
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from tax3d.eval.report import _pick_figures, denoising_figure, write_report

N, M, S, K = 50, 80, 3, 5
SPLITS = ("train", "unseen", "ood")
MAX_FIGURES = 4
TITLE = "<script>alert(1)</script> & evaluation"
PLOTLY_MARKER = "* plotly.js v"


def _episode(rng, split, name, success, exploded=False, true_goal=True, denoising=False) -> dict:
    action = rng.normal([0, 5, 8], [2, 0.01, 2], (N, 3))
    anchor = rng.normal([0, 0, 4], [0.3, 0.3, 2.5], (M, 3))
    goal = action + [0, -5, -1]
    episode = dict(split=split, name=name, success=success, exploded=exploded, rmse=None if exploded else 0.1234,
                   action_pc=action, anchor_pc=anchor, pred_goal=goal + rng.normal(0, 0.1, (S, N, 3)),
                   true_goal=goal if true_goal else None, released_pc=None if exploded else goal - [0, 0, 0.5],
                   grip_vertices=[0, N - 1])
    if denoising:
        noise = goal + rng.normal(0, 3, (N, 3))
        episode["denoising"] = np.stack([noise + t / (K - 1) * (goal - noise) for t in range(K)])
    return episode


def _episodes() -> list[dict]:
    rng = np.random.default_rng(0)
    episodes = [
        _episode(rng, "train", "demo_0", True, denoising=True),
        _episode(rng, "train", "demo_1", False, true_goal=False),
        _episode(rng, "train", "demo_2", True),
        _episode(rng, "unseen", "demo_0", False),
        _episode(rng, "unseen", "demo_1", True, true_goal=False),
        _episode(rng, "ood", "demo_0", False, exploded=True),
        _episode(rng, "ood", "demo_1", True),
    ]
    episodes[3]["pred_goal"][0, :5] = np.nan  # non-finite points must be dropped, not crash the page
    episodes[4]["action_pc"][7] = np.inf
    return episodes


def _summary() -> dict:
    splits = {split: dict(episodes=2, success_rate=0.5, rmse=0.12345, coverage_rmse=None, precision_rmse=None,
                          predict_seconds=1.25, sim_seconds=10.0) for split in SPLITS}
    splits["ood"]["rmse"] = None
    splits["train"]["coverage_rmse"] = 0.0456
    return dict(checkpoint="runs/a.safetensors", task="hangproccloth-simple", variant="cross-displacement",
                command="tax3d evaluate <x>", machine="cpu", date="2025-01-01", splits=splits)


@pytest.fixture(scope="module")
def report(tmp_path_factory) -> Path:
    out_dir = tmp_path_factory.mktemp("report") / "out"
    return write_report(out_dir, _summary(), _episodes(), title=TITLE, max_figures=MAX_FIGURES)


class _TagCounter(HTMLParser):
    TAGS = ("html", "body", "table", "div")

    def __init__(self):
        super().__init__()
        self.opened = dict.fromkeys(self.TAGS, 0)
        self.closed = dict.fromkeys(self.TAGS, 0)
        self.images = []

    def handle_starttag(self, tag, attrs):
        if tag in self.opened:
            self.opened[tag] += 1
        if tag == "img":
            self.images.append(dict(attrs)["src"])

    def handle_endtag(self, tag):
        if tag in self.closed:
            self.closed[tag] += 1


def _parse(page: str) -> _TagCounter:
    parser = _TagCounter()
    parser.feed(page)
    parser.close()
    return parser


def test_page_is_well_formed(report):
    assert report.name == "report.html" and report.is_file()
    parser = _parse(report.read_text())
    assert parser.opened == parser.closed
    assert parser.opened["html"] == parser.opened["body"] == 1
    assert parser.opened["table"] >= 2  # results and the remaining episodes


def test_one_plotly_bundle_and_capped_figures(report):
    page = report.read_text()
    assert page.count(PLOTLY_MARKER) == 1
    shown = sum(not e["exploded"] for e in _episodes())
    assert page.count('class="plotly-graph-div"') == min(MAX_FIGURES, shown) + 1  # + the denoising animation


def test_figures_spread_over_splits_failures_first():
    episodes = _episodes()
    chosen = _pick_figures(episodes, list(SPLITS), MAX_FIGURES)
    assert [len(chosen[s]) for s in SPLITS] == [2, 1, 1]
    assert [episodes[i]["name"] for i in chosen["train"]] == ["demo_1", "demo_0"]
    assert all(not episodes[i]["exploded"] for ids in chosen.values() for i in ids)


def test_images_exist(report):
    out_dir = report.parent
    sources = _parse(report.read_text()).images
    assert sources and all(not s.startswith(("/", "http")) for s in sources)
    assert all((out_dir / s).is_file() for s in sources)
    released = sorted(p.name for p in (out_dir / "images").glob("*_released.png"))
    assert len(released) == sum(not e["exploded"] for e in _episodes())
    assert "ood_demo_0_released.png" not in released  # exploded: no picture
    with Image.open(out_dir / "images" / released[0]) as image:
        assert image.size == (400, 300)
    with Image.open(out_dir / "images" / "overview.png") as image:
        assert image.size[0] >= 400


def test_exploded_episode_listed_as_failed(report):
    page = report.read_text()
    assert "failure (exploded)" in page


def test_results_markdown(report):
    text = (report.parent / "results.md").read_text()
    header = next(line for line in text.splitlines() if line.startswith("| |"))
    assert [c.strip() for c in header.strip("|").split("|")][1:] == list(SPLITS)
    assert re.search(r"\| RMSE \(.\) \| 0\.123 \| 0\.123 \| \u2014 \|", text)
    assert re.search(r"\| Success rate \(.\) \| 0\.50 \| 0\.50 \| 0\.50 \|", text)
    assert re.search(r"\| Coverage RMSE \(.\) \| 0\.046 \| \u2014 \| \u2014 \|", text)
    assert "Precision RMSE" not in text
    assert "runs/a.safetensors" in text and "cross-displacement" in text


def test_no_temporary_files(report):
    leftovers = [p for p in report.parent.rglob("*") if p.name.startswith(".") or p.suffix == ".tmp"]
    assert leftovers == []


def test_strings_are_escaped(report):
    page = report.read_text()
    assert "<script>alert(1)</script>" not in page
    assert "&lt;script&gt;alert(1)&lt;/script&gt; &amp; evaluation" in page
    assert "tax3d evaluate &lt;x&gt;" in page


def test_denoising_figure_has_one_frame_per_step():
    episode = _episodes()[0]
    fig = denoising_figure(episode["denoising"], episode["anchor_pc"])
    assert len(fig.frames) == K
    assert fig.layout.sliders and len(fig.layout.sliders[0].steps) == K


def test_empty_episodes_still_write_the_table(tmp_path):
    page = write_report(tmp_path / "empty", _summary(), []).read_text()
    parser = _parse(page)
    assert parser.opened == parser.closed and parser.opened["table"] == 1
    assert "plotly-graph-div" not in page and "0.123" in page
    assert (tmp_path / "empty" / "results.md").is_file()
    assert (tmp_path / "empty" / "images" / "overview.png").is_file()


def test_fresh_poses_promise_no_true_goal(tmp_path):
    """Episodes on fresh anchor poses have no true goal: the page says why RMSE is '-' and names no green cloud, and
    the overview's legend has no true-goal entry."""
    import numpy as np

    from tax3d.eval.report import NO_TRUE_GOAL, overview_png

    rng = np.random.default_rng(0)
    fresh = [_episode(rng, "unseen", f"episode_{i}", True, true_goal=False) for i in range(2)]
    summary = _summary()
    for split in summary["splits"].values():
        split["rmse"] = None
    page = write_report(tmp_path / "fresh", summary, fresh).read_text()
    assert NO_TRUE_GOAL in page and "true goal green" not in page
    assert "true goal green" in write_report(tmp_path / "demos", _summary(), _episodes()).read_text()
    from matplotlib.figure import Figure

    labels = []
    real = Figure.legend
    Figure.legend = lambda self, handles, names, **kw: labels.extend(names) or real(self, handles, names, **kw)
    try:
        overview_png(tmp_path / "o.png", fresh, ["unseen"])
    finally:
        Figure.legend = real
    assert "true goal" not in labels and "predicted goal" in labels


CHROMIUM = next((p for p in ("/usr/bin/chromium", "/usr/bin/chromium-browser", "/usr/bin/google-chrome")
                 if Path(p).exists()), None)
# After layout, the page lists each episode row's plot and picture boxes (left, right, width) in <pre id="layout">.
LAYOUT_PROBE = """<script>
window.addEventListener("load", () => setTimeout(() => {
  const box = (el) => { const r = el.getBoundingClientRect(); return [r.left, r.right, r.width, r.height]; };
  const rows = [...document.querySelectorAll(".episode-row")].map((row) => ({
    plot: box(row.querySelector(".figure").firstElementChild || row.querySelector(".figure")),
    picture: box(row.querySelector("img") || row.lastElementChild), page: document.documentElement.clientWidth}));
  const pre = document.createElement("pre"); pre.id = "layout"; pre.textContent = JSON.stringify(rows);
  document.body.appendChild(pre);
}, 300));
</script>"""


@pytest.mark.slow
@pytest.mark.skipif(CHROMIUM is None, reason="no headless Chromium on this machine")
@pytest.mark.parametrize("width", [1280, 820])
def test_the_released_cloth_picture_sits_beside_the_3d_plot_in_a_browser(report, tmp_path, width):
    """Rendered by headless Chromium: in every episode row the plot ends where the picture begins, and the picture
    is shown whole inside the window (plotly once drew 1,250 px into an 834 px box, over the picture)."""
    import json
    import subprocess

    probe = report.parent / f"probe_{width}.html"
    probe.write_text(report.read_text().replace("</body>", LAYOUT_PROBE + "</body>"))
    dom = subprocess.run(
        [CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
         "--disable-background-networking", "--disable-component-update", "--disable-sync",
         f"--user-data-dir={tmp_path / 'profile'}", f"--window-size={width},1000", "--virtual-time-budget=10000",
         "--dump-dom", probe.as_uri()], capture_output=True, text=True, timeout=300).stdout
    found = re.search(r'<pre id="layout">(.*?)</pre>', dom, re.S)
    assert found, "the page never finished its layout"
    rows = json.loads(found.group(1).replace("&quot;", '"'))
    assert len(rows) == MAX_FIGURES
    for row in rows:
        plot_left, plot_right, plot_width, plot_height = row["plot"]
        picture_left, picture_right, picture_width, _ = row["picture"]
        assert plot_width > 100 and plot_height > 100  # the plot is drawn
        assert picture_width > 100 and plot_right <= picture_left + 1  # beside the plot, not under it
        assert picture_right <= row["page"] + 1  # inside the window
