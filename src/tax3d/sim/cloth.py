"""The procedural HangProcCloth cloth: a node grid with rectangular holes, its loops, and its .obj mesh."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from tax3d.errors import UsageError

NODE_DENSITY = 25
# The fixed cloth of HangProcCloth-simple (paper, appendix A.2.1).
SIMPLE_CLOTH = {"num_holes": 1, "node_density": 25, "w": 1.0, "h": 1.0, "holes": [{"x0": 8, "x1": 16, "y0": 9, "y1": 13}]}
# The fixed double-hole cloth (docs/reference.md, "HangProcCloth scene").
DOUBLE_HOLE_CLOTH = {
    "num_holes": 2,
    "node_density": 25,
    "w": 1.0,
    "h": 1.0,
    "holes": [{"x0": 8, "x1": 15, "y0": 7, "y1": 10}, {"x0": 11, "x1": 17, "y0": 16, "y1": 19}],
}


@dataclass
class ClothMesh:
    """Grid nodes (row x, column y) that survive the holes, their local coordinates, faces and hole loops."""

    params: dict
    nodes: np.ndarray  # (V, 2) int: (x, y) grid index of each vertex, row-major with hole nodes dropped
    local: np.ndarray  # (V, 3) vertex positions in the mesh file's frame (before the load scale)
    faces: np.ndarray  # (F, 3) int, 0-based
    loops: list[np.ndarray] = field(default_factory=list)  # per hole: vertex ids in polygon order

    @property
    def num_vertices(self) -> int:
        return len(self.nodes)

    def grip_vertices(self) -> tuple[int, int]:
        """Vertices of grid nodes (0, 0) and (0, n - 1): the top corners, 0 and n - 1.

        docs/reference.md, HangProcCloth scene.
        """
        n = self.params["node_density"]
        index = {tuple(v): i for i, v in enumerate(self.nodes)}
        return index[(0, 0)], index[(0, n - 1)]

    def obj_text(self) -> str:
        # Four decimals, as the reference generator writes them: the official vertices carry this rounding.
        lines = [f"v {x:.4f} {y:.4f} {z:.4f}" for x, y, z in self.local]
        lines += [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in self.faces]
        return "\n".join(lines) + "\n"


def validate_cloth_params(params: dict, where: str = "cloth") -> dict:
    """Check node_density, w, h and holes; raises UsageError naming the bad hole."""
    try:
        n = int(params["node_density"])
        w, h = float(params["w"]), float(params["h"])
        holes = [{k: int(hole[k]) for k in ("x0", "x1", "y0", "y1")} for hole in params["holes"]]
    except (KeyError, TypeError, ValueError) as err:
        raise UsageError(f"{where}: cloth parameters need node_density, w, h and holes of x0, x1, y0, y1 ({err})")
    if n < 4 or not (w > 0 and h > 0):
        raise UsageError(f"{where}: node_density {n}, w {w}, h {h}; expected node_density >= 4 and w, h > 0")
    for i, hole in enumerate(holes):
        for lo, hi in (("x0", "x1"), ("y0", "y1")):
            if not 1 <= hole[lo] <= hole[hi] <= n - 2:
                raise UsageError(
                    f"{where}: hole {i} {hole} lies outside the cloth; expected 1 <= {lo} <= {hi} <= {n - 2} "
                    f"so that a ring of nodes surrounds it"
                )
    for i in range(len(holes)):
        for j in range(i + 1, len(holes)):
            a, b = holes[i], holes[j]
            # One node at least between two holes, so each loop vertex borders a single hole.
            apart = a["x1"] + 1 < b["x0"] or b["x1"] + 1 < a["x0"] or a["y1"] + 1 < b["y0"] or b["y1"] + 1 < a["y0"]
            if not apart:
                raise UsageError(f"{where}: holes {i} and {j} overlap or touch; expected at least one node between them")
    return {"num_holes": len(holes), "node_density": n, "w": w, "h": h, "holes": holes}


def build_cloth(params: dict, where: str = "cloth") -> ClothMesh:
    """The mesh of appendix A.2: an n x n grid on [-w, w] x [-h, h] in the file's y-z plane, holes removed."""
    params = validate_cloth_params(params, where)
    n = params["node_density"]
    in_hole = np.zeros((n, n), dtype=bool)
    for hole in params["holes"]:
        in_hole[hole["x0"] : hole["x1"] + 1, hole["y0"] : hole["y1"] + 1] = True
    xs, ys = np.nonzero(~in_hole)  # row-major order: x outer, y inner
    nodes = np.stack([xs, ys], axis=1)
    index = -np.ones((n, n), dtype=int)
    index[xs, ys] = np.arange(len(xs))
    w, h = params["w"], params["h"]
    local = np.stack([np.zeros(len(xs)), -w + 2 * w * xs / (n - 1), -h + 2 * h * ys / (n - 1)], axis=1)
    faces = []
    for x in range(n - 1):
        for y in range(n - 1):
            quad = index[x, y], index[x, y + 1], index[x + 1, y], index[x + 1, y + 1]
            if min(quad) < 0:
                continue
            faces.append((quad[0], quad[1], quad[2]))
            faces.append((quad[1], quad[3], quad[2]))
    loops = [_hole_loop(hole, index) for hole in params["holes"]]
    return ClothMesh(params, nodes, np.round(local, 4), np.array(faces, dtype=int).reshape(-1, 3), loops)


def _hole_loop(hole: dict, index: np.ndarray) -> np.ndarray:
    """Nodes with a 4-neighbour in the hole, ordered: top row, right column down, bottom row back, left column up."""
    x0, x1, y0, y1 = hole["x0"], hole["x1"], hole["y0"], hole["y1"]
    top = [(x0 - 1, y) for y in range(y0, y1 + 1)]
    right = [(x, y1 + 1) for x in range(x0, x1 + 1)]
    bottom = [(x1 + 1, y) for y in range(y1, y0 - 1, -1)]
    left = [(x, y0 - 1) for x in range(x1, x0 - 1, -1)]
    return np.array([index[x, y] for x, y in top + right + bottom + left], dtype=int)


def sample_cloth_params(rng: np.random.Generator, num_holes: int, n: int = NODE_DENSITY) -> dict:
    """Random cloth of appendix A.2: w, h ~ U(0.8, 1.2); holes by DEDO's Monte Carlo rejection sampler."""
    w, h = rng.uniform(0.8, 1.2, size=2)
    for _ in range(1000):
        holes = [_sample_hole(rng, n) for _ in range(num_holes)]
        if all(_inside(hole, n) for hole in holes) and (num_holes < 2 or _apart(holes[0], holes[1])):
            return {"num_holes": num_holes, "node_density": n, "w": float(w), "h": float(h), "holes": holes}
    raise RuntimeError("no valid hole placement found in 1000 tries")


def _sample_hole(rng: np.random.Generator, n: int) -> dict:
    # Corners from x_range = y_range = (2, n - 2), sizes from (5, 7), half-open like numpy's randint (appendix A.2.1).
    x0, y0 = (int(v) for v in rng.integers(2, n - 2, size=2))
    return {"x0": x0, "x1": x0 + int(rng.integers(5, 7)), "y0": y0, "y1": y0 + int(rng.integers(5, 7))}


def _inside(hole: dict, n: int) -> bool:
    # DEDO's boundary check: every corner index strictly between 2 and n - 3.
    return all(2 < v < n - 3 for v in hole.values())


def _apart(a: dict, b: dict, margin: int = 3) -> bool:
    # DEDO's overlap check with a minimum boundary of 3 nodes.
    overlap = a["x0"] < b["x1"] + margin and a["x1"] > b["x0"] - margin
    overlap = overlap and a["y0"] < b["y1"] + margin and a["y1"] > b["y0"] - margin
    return not overlap
