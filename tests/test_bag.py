from collections import Counter
from dataclasses import asdict

import numpy as np
import pybullet
import pytest
import shapely

from tax3d.errors import UsageError
from tax3d.sim.anchor import add_floor, pose_points
from tax3d.sim.bag import BAG_EULER, BAG_POSITION, BAG_SCALE, BagParams, build_bag, load_bag
from tax3d.sim.hook import GOAL_LOCAL, canonical_hook_cloud, goal_position, hook_cloud, load_hook


@pytest.fixture(scope="module")
def bag():
    return build_bag()


def initial_vertices(mesh) -> np.ndarray:
    """The mesh's vertices in the world at the initial pose (BAG_POSITION, BAG_EULER, BAG_SCALE)."""
    rot = np.array(pybullet.getMatrixFromQuaternion(pybullet.getQuaternionFromEuler(BAG_EULER))).reshape(3, 3)
    return BAG_SCALE * mesh.local @ rot.T + np.asarray(BAG_POSITION)


def random_bag(rng: np.random.Generator) -> BagParams:
    """A bag around the default: every size scaled by its own U(0.85, 1.15)."""
    base = BagParams()
    keys = ("width", "depth", "height", "handle_gap", "handle_rise")
    return BagParams(**{**asdict(base), **{k: float(getattr(base, k) * rng.uniform(0.85, 1.15)) for k in keys}})


def _edges(faces):
    return Counter(tuple(sorted(e)) for a, b, c in faces for e in ((a, b), (b, c), (c, a)))


def _components(n, edges):
    parent = list(range(n))

    def find(i):
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    for a, b in edges:
        parent[find(a)] = find(b)
    return len({find(i) for i in range(n)})


def _boundary_cycles(faces):
    """Cycles of the edges used by a single face; each vertex on the boundary has exactly two such edges."""
    boundary = [e for e, count in _edges(faces).items() if count == 1]
    neighbours = {}
    for a, b in boundary:
        neighbours.setdefault(a, []).append(b)
        neighbours.setdefault(b, []).append(a)
    assert all(len(n) == 2 for n in neighbours.values()), "a vertex where two boundary loops touch"
    cycles, seen = [], set()
    for start in neighbours:
        if start in seen:
            continue
        cycle, prev, cur = [start], None, start
        while True:
            seen.add(cur)
            nxt = [v for v in neighbours[cur] if v != prev][0] if prev is not None else neighbours[cur][0]
            if nxt == start:
                break
            cycle.append(nxt)
            prev, cur = cur, nxt
        cycles.append(cycle)
    return cycles


def _cycle_edges(ring):
    ring = list(ring)
    return {tuple(sorted(e)) for e in zip(ring, ring[1:] + ring[:1])}


def test_mesh_size_and_validity(bag):
    v, f = bag.local, bag.faces
    assert 1000 <= bag.num_vertices <= 1400
    assert (bag.num_vertices, len(f)) == (1111, 2080)
    assert f.min() == 0 and f.max() == bag.num_vertices - 1
    assert len(np.unique(f)) == bag.num_vertices  # every vertex is used by a face
    assert all(len(set(t)) == 3 for t in f.tolist())
    area = 0.5 * np.linalg.norm(np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]]), axis=1)
    assert area.min() > 1e-3
    assert len(np.unique(np.round(v, 4), axis=0)) == bag.num_vertices  # no duplicate vertices
    assert len({tuple(sorted(t)) for t in f.tolist()}) == len(f)  # no duplicate faces


def test_surface_is_connected_oriented_manifold(bag):
    f = bag.faces
    counts = _edges(f)
    assert _components(bag.num_vertices, counts) == 1
    assert max(counts.values()) == 2  # manifold: an edge borders one or two faces
    directed = Counter((a, b) for t in f.tolist() for a, b in zip(t, t[1:] + t[:1]))
    assert max(directed.values()) == 1  # consistent orientation: a shared edge runs both ways
    # outward normals: the bottom points down, each wall and strap away from the bag's middle
    v = bag.local
    normal = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    centre = v[f].mean(axis=1)
    bottom = np.all(v[f][:, :, 1] == 0.0, axis=1)
    assert np.all(normal[bottom, 1] < 0)
    side = ~bottom
    middle = np.array([0.0, 0.0, 0.0])
    away = np.einsum("ij,ij->i", normal[side][:, [0, 2]], (centre[side] - middle)[:, [0, 2]])
    assert np.all(away > 0)


def test_each_handle_opening_is_a_hole_in_the_surface(bag):
    """Euler characteristic -1 with three boundary loops: a sphere with three holes (the bag's mouth and the two
    handle openings); each handle's loop is exactly one of those boundary loops."""
    counts = _edges(bag.faces)
    assert bag.num_vertices - len(counts) + len(bag.faces) == -1
    cycles = _boundary_cycles(bag.faces)
    assert len(cycles) == 3
    cycle_edges = [_cycle_edges(c) for c in cycles]
    for loop in bag.loops:
        assert len(set(loop.tolist())) == len(loop)
        assert _cycle_edges(loop) in cycle_edges
    mouth = [c for c in cycle_edges if c not in [_cycle_edges(loop) for loop in bag.loops]]
    assert len(mouth) == 1


def test_handle_openings_are_wide_and_empty(bag):
    p = bag.params
    for loop, z in zip(bag.loops, (p.depth / 2, -p.depth / 2)):
        ring = bag.local[loop]
        assert np.allclose(ring[:, 2], z)  # in the plane of its wall
        polygon = shapely.Polygon(ring[:, :2])
        assert polygon.is_valid
        width, height = np.ptp(ring[:, 0]), np.ptp(ring[:, 1])
        assert width > 1.2 and height > 1.2
        # room for the hook (arm radius 0.1) around the opening's middle
        middle = shapely.Point(0.0, p.height + p.handle_rise / 2)
        assert polygon.contains(middle) and polygon.exterior.distance(middle) > 0.5
        # no vertex of the surface lies inside the opening
        near = np.abs(bag.local[:, 2] - z) < 1e-9
        inside = [polygon.contains(shapely.Point(x, y)) for x, y in bag.local[near][:, :2]]
        assert not any(inside)


def test_handles_and_grip_vertices(bag):
    p = bag.params
    assert len(bag.handles) == len(bag.loops) == 2
    assert not set(bag.handles[0]) & set(bag.handles[1])
    for handle, loop in zip(bag.handles, bag.loops):
        # the opening's loop: the strap's inner edge, closed by rim vertices between the strap's feet
        under = set(loop.tolist()) - set(handle.tolist())
        assert len(under) > 0 and all(bag.local[v, 1] == p.height for v in under)
        feet = handle[bag.local[handle, 1] == p.height]
        assert len(feet) >= 4  # both ends of the strap stand on the rim
    left, right = bag.grip_vertices()
    assert left in bag.handles[0] and right in bag.handles[0] and left not in bag.loops[0]
    # the two shoulders of handle 0: mirror images across the bag, above the rim and below the strap's top
    assert bag.local[left, 0] == -bag.local[right, 0] and bag.local[left, 0] < -0.3
    assert bag.local[left, 1] == bag.local[right, 1]
    assert p.height + 0.5 * p.handle_rise < bag.local[left, 1] < bag.local[bag.handles[0], 1].max()
    world = initial_vertices(bag)
    assert np.all(world[[left, right], 1] < BAG_POSITION[1])  # handle 0 faces the pole (world -y)
    assert world[:, 2].min() == pytest.approx(BAG_POSITION[2])  # the bottom at the initial height


def test_obj_round_trip(bag, tmp_path):
    path = tmp_path / "bag.obj"
    bag.write_obj(path)
    verts, faces = [], []
    for line in path.read_text().splitlines():
        kind, *rest = line.split()
        if kind == "v":
            verts.append([float(x) for x in rest])
        elif kind == "f":
            faces.append([int(x) - 1 for x in rest])
    assert np.array_equal(np.array(verts), bag.local)
    assert np.array_equal(np.array(faces), bag.faces)


def test_random_bags_and_bad_params():
    rng = np.random.default_rng(0)
    for _ in range(5):
        mesh = build_bag(random_bag(rng))
        assert mesh.num_vertices - len(_edges(mesh.faces)) + len(mesh.faces) == -1
        assert len(_boundary_cycles(mesh.faces)) == 3
        assert 3.0 <= np.ptp(mesh.local[:, 0]) <= 4.1
    with pytest.raises(UsageError, match="handle gap"):
        build_bag(BagParams(handle_gap=3.4))
    with pytest.raises(UsageError, match="even number"):
        build_bag(BagParams(handle_segments=7))


def test_hook_bodies_and_cloud():
    client = pybullet.connect(pybullet.DIRECT)
    try:
        hook, pole = load_hook(client)
        (lo, hi) = pybullet.getAABB(hook, physicsClientId=client)
        # the arm reaches past the goal (y = 1.28) just above it; the pin stands up to z = 9.75
        assert hi[1] == pytest.approx(1.38, abs=0.02) and 9.2 < lo[2] < 9.3 and hi[2] == pytest.approx(9.75)
        (lo, hi) = pybullet.getAABB(pole, physicsClientId=client)
        assert lo[2] == pytest.approx(0.0, abs=1e-6) and hi[2] == pytest.approx(10.0)
        # the pose moves the bodies like the points: p -> Rz p + trans
        rot, trans = 0.7, np.array([2.0, -3.0, 1.0])
        moved, _ = load_hook(client, rot, trans)
        pos, _ = pybullet.getBasePositionAndOrientation(moved, physicsClientId=client)
        assert np.allclose(pos, pose_points(GOAL_LOCAL[None], rot, trans)[0])
        assert np.allclose(goal_position(rot, trans), pos)
    finally:
        pybullet.disconnect(client)
    cloud = canonical_hook_cloud(True)
    assert 1000 < len(cloud) < 2000
    arm = cloud[(cloud[:, 1] > 0.4) & (cloud[:, 2] > 8.5)]  # points on the hook, clear of the pole
    assert len(arm) > 20 and arm[:, 1].max() > 1.3
    assert np.allclose(hook_cloud(rot, trans), pose_points(cloud, rot, trans))


def test_bag_soft_body_hangs_from_its_grips_without_blowing_up(bag, tmp_path):
    client = pybullet.connect(pybullet.DIRECT)
    try:
        pybullet.resetSimulation(pybullet.RESET_USE_DEFORMABLE_WORLD, physicsClientId=client)
        pybullet.setGravity(0, 0, -9.8, physicsClientId=client)
        pybullet.setTimeStep(1.0 / 500.0, physicsClientId=client)
        add_floor(client)
        load_hook(client)
        body = load_bag(client, bag, tmp_path / "bag_1.obj")
        pybullet.setPhysicsEngineParameter(sparseSdfVoxelSize=0.25, physicsClientId=client)

        def vertices():
            _, v = pybullet.getMeshData(body, -1, flags=pybullet.MESH_DATA_SIMULATION_MESH, physicsClientId=client)
            return np.asarray(v)

        start = vertices()
        assert np.allclose(start, initial_vertices(bag), atol=1e-4)  # same vertex order as the file
        for v in bag.grip_vertices():  # pinned in place, as if held by two grippers
            pybullet.createSoftBodyAnchor(body, v, -1, -1, physicsClientId=client)
        for _ in range(50):
            pybullet.stepSimulation(physicsClientId=client)
        end = vertices()
    finally:
        pybullet.disconnect(client)
    assert np.all(np.isfinite(end))
    assert np.linalg.norm(end - start, axis=1).max() < 0.5
    assert np.all(np.ptp(end, axis=0) < np.ptp(start, axis=0) + 0.5)
    grips = list(bag.grip_vertices())
    assert np.allclose(end[grips], start[grips], atol=1e-3)
