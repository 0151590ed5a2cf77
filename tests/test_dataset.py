from pathlib import Path

import numpy as np
import pytest
import torch
from torch.utils.data import DataLoader

from tax3d.data.dataset import DemoDataset, make_sample, make_target, split_demos
from tax3d.data.format import DemoError
from tax3d.errors import UsageError
from tax3d.frames import frame_inputs, to_world
from tax3d.geometry import farthest_point_sample, rotate_z
from tax3d.variants import VARIANTS, variant_spec

from tests.conftest import write_demos

OFFICIAL = Path(__file__).resolve().parents[1] / ".." / "shared" / "data" / "tax3d-official"
NA, NB = 16, 24  # points sampled per cloud in these tests


@pytest.fixture
def demo_dir(tmp_path):
    folder = tmp_path / "demos"
    return folder, write_demos(folder, 3)


def clouds(demo):
    return demo["action_pc"], demo["anchor_pc"], demo["action_pc"] + demo["flow"]


def gen(seed=0):
    return torch.Generator().manual_seed(seed)


def close(a, b, atol=1e-5):
    torch.testing.assert_close(torch.as_tensor(a, dtype=torch.float32), torch.as_tensor(b, dtype=torch.float32),
                               atol=atol, rtol=0)


def test_variant_specs():
    assert len(VARIANTS) == 10
    for name in VARIANTS:
        assert variant_spec(name).name == name
    assert variant_spec("CD-W") == variant_spec("cd_w")
    cd, cp_w, cd_nac, sp, rd = (variant_spec(v) for v in ("cd", "cp_w", "cd_nac", "sp", "rd"))
    assert cd.target == "displacement" and cd.object_centric and cd.action_context and cd.diffusion
    assert cp_w.target == "point" and not cp_w.object_centric
    assert not cd_nac.action_context and cd_nac.object_centric
    assert sp.scene and sp.target == "point"
    assert not rd.diffusion and rd.target == "displacement"


def test_unknown_variant_is_a_usage_error():
    with pytest.raises(UsageError, match=r"unknown variant 'xyz'; expected one of cd, cp, cd_w"):
        variant_spec("xyz")


@pytest.mark.parametrize("variant", VARIANTS)
@pytest.mark.parametrize("rotate", [False, True])
def test_to_world_inverts_the_target(demo_dir, variant, rotate):
    _, demos = demo_dir
    action, anchor, goal = clouds(demos[0])
    spec = variant_spec(variant)
    s = make_sample(action, anchor, goal, spec, gen(3), NA, NB, rotate=rotate)
    close(to_world(s["target"], s, spec), s["goal"])

    idx = s["action_idx"].numpy()
    close(s["action"] + s["action_mean"], action[idx])  # the action is never rotated
    if rotate:
        assert s["angle"] != 0
        # The augmented scene: anchor and goal turned about the pivot; its goal is what to_world returns.
        expected = rotate_z(torch.from_numpy(goal[idx]) - s["pivot"].double(), float(s["angle"])) + s["pivot"].double()
        close(s["goal"], expected)
    else:
        assert s["angle"] == 0
        close(s["goal"], goal[idx])


@pytest.mark.parametrize("variant", ["cd", "cp", "sd"])
def test_scene_rotation_turns_inputs_and_target_together(demo_dir, variant):
    """The whole scene turned about z: every frame input and the target are the plain sample's, turned by one
    angle (the object-centric frames make the cross-displacement equivariant), and to_world still gives the goal."""
    _, demos = demo_dir
    action, anchor, goal = clouds(demos[0])
    spec = variant_spec(variant)
    indices = (farthest_point_sample(torch.from_numpy(action), NA, start=gen(5)),
               farthest_point_sample(torch.from_numpy(anchor), NB, start=gen(6)))
    plain = make_sample(action, anchor, goal, spec, gen(7), indices=indices)
    turned = make_sample(action, anchor, goal, spec, gen(7), indices=indices, rotate_scene=True)
    angle = float(torch.atan2(turned["anchor"][0, 1], turned["anchor"][0, 0])
                  - torch.atan2(plain["anchor"][0, 1], plain["anchor"][0, 0]))
    assert abs(np.sin(angle)) > 1e-3
    for key in ("action", "anchor", "target"):
        close(turned[key], rotate_z(plain[key].double(), angle).float(), atol=1e-4)
    close(to_world(turned["target"], turned, spec), turned["goal"])
    if spec.object_centric:
        close(turned["anchor_mean"], plain["anchor_mean"])  # the pivot is the anchor mean
    assert not torch.allclose(turned["action_mean"], plain["action_mean"], atol=1e-3)


def test_scene_rotation_is_drawn_per_sample_and_never_cached(demo_dir):
    folder, _ = demo_dir
    kwargs = dict(num_action_points=NA, num_anchor_points=NB, subsets=2, rotate=False, train_size=12)
    turned = DemoDataset(folder, "cd", rotate_scene=True, **kwargs)
    assert turned.cached is None and DemoDataset(folder, "cd", **kwargs).cached is not None
    assert DemoDataset(folder, "cd", occlusion=0.5, **kwargs).cached is None  # a cut drawn per sample too
    means = {tuple(turned[i]["action_mean"].tolist()) for i in range(0, 4 * len(turned.demos), len(turned.demos))}
    assert len(means) == 4  # demo 0, four times, four turns


def test_an_occluded_cloud_keeps_its_size_and_each_points_own_goal(demo_dir):
    _, demos = demo_dir
    action, anchor, goal = clouds(demos[0])
    plain = make_sample(action, anchor, goal, "cd", gen(2), NA, NB)
    cut = [make_sample(action, anchor, goal, "cd", gen(seed), NA, NB, indices=(plain["action_idx"],
                       farthest_point_sample(torch.from_numpy(anchor), NB, start=gen(2))), occlusion=0.99)
           for seed in range(8)]
    changed = [s for s in cut if not torch.equal(s["action_idx"], plain["action_idx"])]
    assert changed  # some draws hide a part
    for s in changed:
        assert s["action"].shape == plain["action"].shape
        rows = s["action_idx"].numpy()
        assert len(set(rows.tolist())) < NA and set(rows.tolist()) <= set(plain["action_idx"].tolist())
        close(s["goal"], goal[rows])  # every point keeps its own goal
        close(to_world(s["target"], s, variant_spec("cd")), s["goal"])
    assert torch.equal(make_sample(action, anchor, goal, "cd", gen(2), NA, NB, occlusion=0.0)["action_idx"],
                       plain["action_idx"])


def test_a_cut_that_would_hide_most_points_hides_none():
    from tax3d.data.dataset import occluded

    points = torch.tensor([[0.0, 0, 0], [1, 0, 0], [2, 0, 0], [3, 0, 0]], dtype=torch.float64)
    rows = torch.arange(4)
    for seed in range(20):
        out = occluded(points, gen(seed), rows)
        hidden = 4 - len(set(out.tolist()))
        assert hidden * 2 <= 4 and len(out) == 4


def test_rotation_pivot_is_the_anchor_mean_except_world_frame(demo_dir):
    _, demos = demo_dir
    action, anchor, goal = clouds(demos[0])
    for variant in ("cd", "sd", "cd_w"):
        s = make_sample(action, anchor, goal, variant, gen(1), NA, NB, rotate=True)
        anchor_world = s["anchor"] + s["anchor_mean"]
        expected = torch.zeros(3) if variant == "cd_w" else anchor_world.mean(0)
        close(s["pivot"], expected)


def test_object_centric_frames_and_targets(demo_dir):
    _, demos = demo_dir
    action, anchor, goal = clouds(demos[1])
    cd = make_sample(action, anchor, goal, "cd", gen(0), NA, NB)
    cp = make_sample(action, anchor, goal, "cp", gen(0), NA, NB)
    close(cd["action"].mean(0), torch.zeros(3))
    close(cd["anchor"].mean(0), torch.zeros(3))
    goal_in_anchor_frame = cd["goal"] - cd["anchor_mean"]
    close(cd["target"], goal_in_anchor_frame - cd["action"])
    close(cp["target"], goal_in_anchor_frame)


def test_world_frame_variants_do_not_centre(demo_dir):
    _, demos = demo_dir
    action, anchor, goal = clouds(demos[1])
    s = make_sample(action, anchor, goal, "cp_w", gen(0), NA, NB)
    close(s["action_mean"], torch.zeros(3))
    close(s["anchor_mean"], torch.zeros(3))
    close(s["action"], action[s["action_idx"].numpy()])
    close(s["target"], s["goal"])


@pytest.mark.parametrize("variant", ["sd", "sp"])
def test_scene_variants(demo_dir, variant):
    _, demos = demo_dir
    action, anchor, goal = clouds(demos[2])
    s = make_sample(action, anchor, goal, variant, gen(0), NA, NB)
    assert s["target"].shape == (NA + NB, 3)
    scene = torch.cat([s["action"], s["anchor"]])
    close(scene.mean(0), torch.zeros(3))
    close(s["action_mean"], s["anchor_mean"])
    anchor_target = s["target"][NA:]
    close(anchor_target, torch.zeros(NB, 3) if variant == "sd" else s["anchor"])
    close(to_world(s["target"][:NA], s, variant_spec(variant)), s["goal"])  # action rows alone also work


@pytest.mark.parametrize("variant", VARIANTS)
def test_translating_the_scene(demo_dir, variant):
    _, demos = demo_dir
    action, anchor, goal = clouds(demos[0])
    shift = np.array([3.0, -7.0, 2.0])
    spec = variant_spec(variant)
    for rotate in (False, True):
        a = make_sample(action, anchor, goal, spec, gen(5), NA, NB, rotate=rotate)
        b = make_sample(action + shift, anchor + shift, goal + shift, spec, gen(5), NA, NB, rotate=rotate)
        assert torch.equal(a["action_idx"], b["action_idx"])
        if spec.object_centric or spec.scene or not rotate:
            close(b["goal"], a["goal"] + torch.tensor(shift, dtype=torch.float32))
        same = {key: torch.allclose(a[key], b[key], atol=1e-5) for key in ("action", "anchor", "target")}
        if spec.object_centric or spec.scene:
            assert all(same.values()), same
            close(b["anchor_mean"], a["anchor_mean"] + torch.tensor(shift, dtype=torch.float32))
        else:
            assert not same["action"] and not same["anchor"]
            # A world-frame displacement ignores a common shift unless the scene turns about the origin.
            assert same["target"] == (spec.target == "displacement" and not rotate)


@pytest.mark.parametrize("pair", [("cd", "cd_nac"), ("cp", "cp_nac"), ("cd", "rd"), ("cp", "rp")])
def test_nac_and_regression_samples_equal_cd_cp(demo_dir, pair):
    """The dataset gives NAC and RD/RP the CD/CP items; the model ignores the action context for NAC."""
    folder, _ = demo_dir
    a, b = (DemoDataset(folder, v, num_action_points=NA, num_anchor_points=NB, seed=2) for v in pair)
    for key, value in a[1].items():
        assert torch.equal(value, b[1][key]), key
    assert not variant_spec(pair[1]).action_context or not variant_spec(pair[1]).diffusion


def test_batch_and_full_cloud_round_trip(demo_dir):
    folder, demos = demo_dir
    for variant in ("cd", "cp_w", "sp"):
        spec = variant_spec(variant)
        ds = DemoDataset(folder, variant, num_action_points=NA, num_anchor_points=NB)
        batch = next(iter(DataLoader(ds, batch_size=3)))
        assert batch["target"].shape[0] == 3
        close(to_world(batch["target"], batch, spec), batch["goal"])

        # Evaluation: the full action cloud, no goal; a stack of predictions for one scene.
        action, anchor, goal = (torch.from_numpy(x) for x in clouds(demos[0]))
        frames = frame_inputs(action, anchor, spec)
        prediction = make_target(goal, frames, spec).expand(5, -1, -1)
        world = to_world(prediction, frames, spec)
        assert world.shape == (5, len(action), 3)
        torch.testing.assert_close(world, goal.expand(5, -1, -1))


def test_dataset_items(demo_dir):
    folder, _ = demo_dir
    ds = DemoDataset(folder, "cd", num_action_points=NA, num_anchor_points=NB)
    assert len(ds) == 3
    item = ds[0]
    shapes = {key: tuple(value.shape) for key, value in item.items()}
    assert shapes == {"action": (NA, 3), "anchor": (NB, 3), "action_mean": (3,), "anchor_mean": (3,),
                      "target": (NA, 3), "goal": (NA, 3), "angle": (), "pivot": (3,), "action_idx": (NA,),
                      "demo_index": ()}
    assert all(v.dtype == torch.float32 for k, v in item.items() if k not in ("action_idx", "demo_index"))
    assert len(set(item["action_idx"].tolist())) == NA
    with pytest.raises(IndexError):
        ds[3]


@pytest.mark.parametrize("variant", ["cd", "sd"])
def test_grip_weight_marks_the_grasped_vertices(demo_dir, variant):
    """grip_weight: the rows of the demo's gripper vertices (vertex 0 here) get it, every other row 1 (SD: the
    anchor rows too); the default adds no weights at all."""
    folder, _ = demo_dir
    full = DemoDataset(folder, variant, num_action_points=None, num_anchor_points=NB, grip_weight=8.0)[0]
    expected = torch.ones(len(full["target"]))
    expected[0] = 8.0
    assert torch.equal(full["point_weight"], expected)
    sampled = DemoDataset(folder, variant, num_action_points=NA, num_anchor_points=NB, grip_weight=8.0, subsets=2)
    for item in (sampled[i] for i in range(3)):
        assert torch.equal(item["point_weight"][:NA] == 8.0, item["action_idx"] == 0)
    assert "point_weight" not in DemoDataset(folder, variant, num_action_points=NA, num_anchor_points=NB)[0]
    with pytest.raises(UsageError, match="grip_weight"):
        DemoDataset(folder, variant, grip_weight=0.0)



def test_grasped_vertices_come_from_the_file_and_a_demo_without_them_is_weighted_uniformly(tmp_path, capsys):
    """The rows an `anchors` key names get grip_weight; a demo without `anchors` gets weight 1 everywhere, and the
    run is told once on stderr (not once per demo or per item)."""
    from tax3d.data import write_demo

    rng = np.random.default_rng(0)
    action, anchor = rng.normal(size=(12, 3)), rng.normal(size=(9, 3))
    write_demo(tmp_path / "demo_0.npz", action, anchor, flow=np.ones((12, 3)),
               anchors={7: {"pos": action[3], "vertices": [3]}, 8: {"pos": action[10], "vertices": [10]}})
    write_demo(tmp_path / "demo_1.npz", action, anchor, flow=np.ones((12, 3)))
    write_demo(tmp_path / "demo_2.npz", action, anchor, flow=np.ones((12, 3)))
    ds = DemoDataset(tmp_path, "cd", num_action_points=None, num_anchor_points=None, grip_weight=5.0)
    weighted = ds[0]["point_weight"]
    assert torch.equal(torch.nonzero(weighted == 5.0).flatten(), torch.tensor([3, 10]))
    assert torch.equal(weighted[weighted != 5.0], torch.ones(10))
    assert torch.equal(ds[1]["point_weight"], torch.ones(12)) and torch.equal(ds[2]["point_weight"], torch.ones(12))
    err = capsys.readouterr().err
    assert err.count("note:") == 1 and "2 of 3 demos" in err and "demo_1.npz" in err and "weighted 1" in err
    DemoDataset(tmp_path, "cd", num_action_points=None, num_anchor_points=None)
    assert capsys.readouterr().err == ""  # grip_weight 1: nothing to say

def test_rotation_is_on_for_training_only(demo_dir):
    folder, _ = demo_dir
    kwargs = dict(num_action_points=NA, num_anchor_points=NB)
    assert DemoDataset(folder, "cd", **kwargs)[0]["angle"] != 0
    assert DemoDataset(folder, "cd", train=False, **kwargs)[0]["angle"] == 0
    assert DemoDataset(folder, "cd", rotate=False, **kwargs)[0]["angle"] == 0


def test_full_clouds_and_padding(demo_dir):
    folder, demos = demo_dir
    ds = DemoDataset(folder, "cd", num_action_points=None, num_anchor_points=100, train=False)
    item = ds[0]
    assert torch.equal(item["action_idx"], torch.arange(40))
    assert item["anchor"].shape == (100, 3)  # 60 points, padded by repetition
    close(item["goal"], clouds(demos[0])[2])


def test_train_size_repeats_demos(demo_dir):
    folder, _ = demo_dir
    ds = DemoDataset(folder, "cd", num_action_points=NA, num_anchor_points=NB, train_size=10)
    assert len(ds) == 10
    assert [int(ds[i]["demo_index"]) for i in (0, 4, 9)] == [0, 1, 0]
    with pytest.raises(UsageError):
        DemoDataset(folder, "cd", train_size=0)


def test_an_epoch_holds_every_demo_when_they_outnumber_train_size(demo_dir):
    """More demos than train_size: an epoch still samples each of them, none left out of training."""
    folder, _ = demo_dir
    ds = DemoDataset(folder, "cd", num_action_points=NA, num_anchor_points=NB, train_size=2)
    assert len(ds) == 3 and sorted(int(ds[i]["demo_index"]) for i in range(len(ds))) == [0, 1, 2]


def test_determinism(demo_dir):
    folder, _ = demo_dir
    make = lambda seed: DemoDataset(folder, "cp", num_action_points=NA, num_anchor_points=NB, seed=seed)  # noqa: E731
    a, b = make(7), make(7)
    b[2]  # the order of access does not matter
    for key, value in a[1].items():
        assert torch.equal(value, b[1][key]), key
    assert not torch.equal(a[1]["target"], make(8)[1]["target"])
    b.set_epoch(1)
    assert a[1]["angle"] != b[1]["angle"]


def test_empty_folder_and_bad_file(tmp_path):
    empty = tmp_path / "empty"
    empty.mkdir()
    with pytest.raises(DemoError, match="empty") as err:
        DemoDataset(empty, "cd")
    assert "\n" not in str(err.value)
    with pytest.raises(DemoError, match="no such demonstration folder"):
        DemoDataset(tmp_path / "missing", "cd")
    (empty / "demo_0.npz").write_bytes(b"not a zip file")
    with pytest.raises(DemoError, match="demo_0.npz"):
        DemoDataset(empty, "cd")


def test_several_folders_and_split(tmp_path):
    write_demos(tmp_path / "a", 6, seed=1)
    write_demos(tmp_path / "b", 4, seed=2)
    ds = DemoDataset([tmp_path / "a", tmp_path / "b"], "cd", num_action_points=NA, num_anchor_points=NB)
    assert len(ds) == 10
    train, val = split_demos(tmp_path / "a", val_fraction=0.34, seed=0)
    assert len(val) == 2 and len(train) == 4
    assert sorted(train + val) == sorted((tmp_path / "a").glob("demo_*.npz"))
    assert split_demos(tmp_path / "a", 0.34, seed=0) == (train, val)
    assert len(DemoDataset(val, "cd", num_action_points=NA, num_anchor_points=NB)) == 2
    with pytest.raises(UsageError):
        split_demos([train[0]], 0.5)
    with pytest.raises(UsageError):
        split_demos(tmp_path / "a", 1.0)


def test_official_demos():
    root = OFFICIAL / "hangproccloth-simple"
    if not root.is_dir():
        pytest.skip(f"official demonstrations not found at {OFFICIAL.resolve()}")
    files = [root / "train" / "demo_0.npz", root / "val" / "demo_0.npz"]
    for variant in ("cd", "sp"):
        spec = variant_spec(variant)
        ds = DemoDataset(files, variant)
        batch = next(iter(DataLoader(ds, batch_size=2)))
        assert batch["action"].shape == (2, 512, 3) and batch["anchor"].shape == (2, 512, 3)
        assert torch.isfinite(batch["target"]).all()
        close(to_world(batch["target"], batch, spec), batch["goal"])


@pytest.mark.parametrize("rotate", [False, True])
def test_cached_subsets(demo_dir, rotate):
    """subsets > 0: each demo's farthest-point subsets are drawn once (deterministic in the seed), items pick one
    of them, every demo is covered, and the items equal make_sample on those rows."""
    folder, demos = demo_dir
    make = lambda seed: DemoDataset(folder, "cd", num_action_points=NA, num_anchor_points=NB,  # noqa: E731
                                    train_size=60, seed=seed, subsets=4, rotate=rotate)
    a, b = make(3), make(3)
    assert len(a.subsets) == 3 and all(len(s) == 4 for s in a.subsets)
    for sa, sb in zip(a.subsets, b.subsets):
        for (ia, ja), (ib, jb) in zip(sa, sb):
            assert torch.equal(ia, ib) and torch.equal(ja, jb)
    assert any(not torch.equal(x[0], y[0]) for x, y in zip(a.subsets[0], make(4).subsets[0]))
    action = torch.as_tensor(demos[0]["action_pc"])
    for idx, _ in a.subsets[0]:
        assert len(set(idx.tolist())) == NA  # distinct rows
        first = idx[0].item()
        assert torch.equal(idx, farthest_point_sample(action, NA, start=first))
    seen = {(int(a[i]["demo_index"]), tuple(a[i]["action_idx"][:3].tolist())) for i in range(60)}
    assert {d for d, _ in seen} == {0, 1, 2}
    assert len(seen) > 3  # more than one subset per demo is used
    item = a[5]
    subset = next(s for s in a.subsets[int(item["demo_index"])] if torch.equal(s[0], item["action_idx"]))
    angle_gen = a.generator(5)
    torch.randint(4, (), generator=angle_gen)
    expected = make_sample(*clouds(demos[int(item["demo_index"])]), "cd", angle_gen, NA, NB, rotate,
                           indices=subset)
    for key in ("action", "anchor", "target", "goal"):
        assert torch.equal(item[key], expected[key]), key
    with pytest.raises(UsageError):
        DemoDataset(folder, "cd", subsets=-1)
