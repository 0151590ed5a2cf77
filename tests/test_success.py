import numpy as np

from tax3d.sim.success import centroid_check, cloth_success, polygon_check


def square_loop(centre, half=1.0, z=8.0, n=4):
    """An ordered square ring of 4n points around centre in the xy plane."""
    t = np.linspace(-half, half, n, endpoint=False)
    top = [(x, half) for x in t]
    right = [(half, -y) for y in t]
    bottom = [(-x, -half) for x in t]
    left = [(-half, y) for y in t]
    ring = np.array(top + right + bottom + left)
    return np.column_stack([ring + np.asarray(centre)[:2], np.full(len(ring), z)])


def test_polygon_check_inside_and_outside():
    goal = np.array([0.0, 0.0, 8.2])
    cloth = square_loop((0, 0))
    loop = np.arange(len(cloth))
    assert polygon_check(cloth, loop, goal)
    assert not polygon_check(square_loop((3, 0)), loop, goal)
    # order matters: the four corners taken crosswise make an hourglass (two triangles meeting at the centre),
    # which holds points above and below the centre but not one beside it
    corners = square_loop((0, 0), n=1)
    beside, above = np.array([0.5, 0.0, 8.2]), np.array([0.0, 0.5, 8.2])
    assert polygon_check(corners, np.arange(4), beside) and polygon_check(corners, np.arange(4), above)
    hourglass = np.array([0, 1, 3, 2])
    assert not polygon_check(corners, hourglass, beside)
    assert polygon_check(corners, hourglass, above)


def test_centroid_check_threshold():
    goal = np.array([0.0, 0.0, 8.2])
    loop = np.arange(16)
    assert centroid_check(square_loop((0, 0), z=8.2 - 1.2), loop, goal, 1.3)
    assert not centroid_check(square_loop((0, 0), z=8.2 - 1.4), loop, goal, 1.3)


def test_cloth_success_needs_both_checks_on_one_hole():
    goal = np.array([0.0, 0.0, 8.2])
    near = square_loop((0, 0), z=8.0)
    fallen = square_loop((0, 0), z=2.0)  # still around the rod in xy, far below
    away = square_loop((4, 0), z=8.0)
    loop = np.arange(16)
    assert cloth_success(near, fallen, [loop], goal)["success"]  # polygon is checked in xy only
    assert not cloth_success(near, away, [loop], goal)["success"]
    assert not cloth_success(away, near, [loop], goal)["success"]
    # two holes: one passing hole is enough; a hole passing only one check each is not
    both = np.concatenate([away, near])
    loops = [np.arange(16), np.arange(16, 32)]
    result = cloth_success(both, both, loops, goal)
    assert result["success"] and result["holes"][0] == {"centroid": False, "polygon": False}
    split = cloth_success(np.concatenate([near, away]), np.concatenate([away, near]), loops, goal)
    assert not split["success"]
