import numpy as np
import pytest

from tax3d.errors import UsageError
from tax3d.sim.cloth import DOUBLE_HOLE_CLOTH, SIMPLE_CLOTH, build_cloth, sample_cloth_params


def test_simple_cloth_nodes_and_removed_hole():
    mesh = build_cloth(SIMPLE_CLOTH)
    assert mesh.num_vertices == 580
    kept = {tuple(n) for n in mesh.nodes}
    removed = {(x, y) for x in range(25) for y in range(25)} - kept
    # rows x 8..16 and columns y 9..13, both inclusive: 9 x 5 nodes
    assert removed == {(x, y) for x in range(8, 17) for y in range(9, 14)}
    # row-major order with the hole's nodes dropped
    assert [tuple(n) for n in mesh.nodes[:3]] == [(0, 0), (0, 1), (0, 2)]
    assert np.all(np.diff(mesh.nodes[:, 0] * 25 + mesh.nodes[:, 1]) > 0)


def test_grip_vertices_are_top_corners():
    mesh = build_cloth(SIMPLE_CLOTH)
    assert mesh.grip_vertices() == (0, 24)


def test_loop_vertices_and_order():
    mesh = build_cloth(SIMPLE_CLOTH)
    (loop,) = mesh.loops
    assert len(loop) == 28
    nodes = [tuple(mesh.nodes[v]) for v in loop]
    assert nodes[:5] == [(7, y) for y in range(9, 14)]  # top row, left to right
    assert nodes[5:14] == [(x, 14) for x in range(8, 17)]  # right column, downwards
    assert nodes[14:19] == [(17, y) for y in range(13, 8, -1)]  # bottom row, reversed
    assert nodes[19:] == [(x, 8) for x in range(16, 7, -1)]  # left column, upwards
    # every loop vertex has a 4-neighbour in the hole, and no other vertex has one
    hole = {(x, y) for x in range(8, 17) for y in range(9, 14)}
    touching = {i for i, (x, y) in enumerate(map(tuple, mesh.nodes))
                if {(x + 1, y), (x - 1, y), (x, y + 1), (x, y - 1)} & hole}
    assert touching == set(loop.tolist())


def test_local_coordinates_and_faces():
    mesh = build_cloth({**SIMPLE_CLOTH, "w": 0.9, "h": 1.1})
    assert np.allclose(mesh.local[:, 0], 0)
    assert mesh.local[:, 1].min() == pytest.approx(-0.9) and mesh.local[:, 1].max() == pytest.approx(0.9)
    assert mesh.local[:, 2].min() == pytest.approx(-1.1) and mesh.local[:, 2].max() == pytest.approx(1.1)
    # 24 x 24 quads, minus the quads touching a removed node: (9 + 1) x (5 + 1) = 60 quads, two triangles each
    assert len(mesh.faces) == 2 * (24 * 24 - 60)
    assert mesh.faces.max() < mesh.num_vertices
    assert "v 0.0000 -0.9000 -1.1000" in mesh.obj_text()


def test_double_hole_cloth():
    mesh = build_cloth(DOUBLE_HOLE_CLOTH)
    assert mesh.num_vertices == 625 - 8 * 4 - 7 * 4
    assert [len(loop) for loop in mesh.loops] == [2 * 8 + 2 * 4, 2 * 7 + 2 * 4]
    assert not set(mesh.loops[0]) & set(mesh.loops[1])


@pytest.mark.parametrize("num_holes", [1, 2])
def test_random_cloth_ranges(num_holes):
    rng = np.random.default_rng(0)
    for _ in range(200):
        params = sample_cloth_params(rng, num_holes)
        assert 0.8 <= params["w"] <= 1.2 and 0.8 <= params["h"] <= 1.2
        assert len(params["holes"]) == num_holes
        for hole in params["holes"]:
            assert all(2 < v < 22 for v in hole.values())
            assert hole["x1"] - hole["x0"] in (5, 6) and hole["y1"] - hole["y0"] in (5, 6)
        mesh = build_cloth(params)
        assert mesh.grip_vertices() == (0, 24)
        assert all(len(loop) == 2 * (h["x1"] - h["x0"] + 1) + 2 * (h["y1"] - h["y0"] + 1)
                   for loop, h in zip(mesh.loops, params["holes"]))


@pytest.mark.parametrize(
    "holes, words",
    [
        ([{"x0": 0, "x1": 5, "y0": 9, "y1": 13}], "outside the cloth"),
        ([{"x0": 8, "x1": 24, "y0": 9, "y1": 13}], "outside the cloth"),
        ([{"x0": 8, "x1": 6, "y0": 9, "y1": 13}], "outside the cloth"),
        ([{"x0": 3, "x1": 8, "y0": 3, "y1": 8}, {"x0": 8, "x1": 12, "y0": 8, "y1": 12}], "overlap"),
        ([{"x0": 3, "x1": 8}], "need node_density"),
    ],
)
def test_bad_holes(holes, words):
    with pytest.raises(UsageError, match=words):
        build_cloth({**SIMPLE_CLOTH, "holes": holes}, where="demo_3.npz")
