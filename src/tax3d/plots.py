"""Static pictures of demonstrations: initial cloth, goal cloth and anchor cloud in 3D."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np


def plot_demos(demos: list[dict], titles: list[str], path: str | os.PathLike) -> Path:
    """One 3D panel per demo (action: initial cloth, goal: action + flow, anchor), written atomically as PNG."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    path = Path(path)
    fig = plt.figure(figsize=(4.5 * len(demos), 4.5))
    for i, (demo, title) in enumerate(zip(demos, titles)):
        ax = fig.add_subplot(1, len(demos), i + 1, projection="3d")
        action, anchor = demo["action_pc"], demo["anchor_pc"]
        goal = action + demo["flow"]
        ax.scatter(*anchor.T, s=1, c="0.45", label="anchor")
        ax.scatter(*action.T, s=2, c="tab:blue", label="action (initial)")
        ax.scatter(*goal.T, s=2, c="tab:green", label="goal")
        every = np.concatenate([anchor, action, goal])
        centre, half = every.mean(0), (every.max(0) - every.min(0)).max() / 2
        ax.set(xlim=(centre[0] - half, centre[0] + half), ylim=(centre[1] - half, centre[1] + half),
               zlim=(max(0.0, centre[2] - half), centre[2] + half), title=title)
        ax.view_init(elev=20, azim=-40)
        if i == 0:
            ax.legend(loc="upper left", fontsize=7)
    fig.tight_layout()
    tmp = path.with_name(f".{path.name}.tmp")
    fig.savefig(tmp, dpi=110, format="png")
    plt.close(fig)
    os.replace(tmp, path)
    return path
