import numpy as np
import pytest

from tax3d.errors import UsageError
from tax3d.sim.tasks import TASKS, episode_params, get_split, get_task, sample_anchor_pose


@pytest.mark.parametrize("ood", [False, True])
def test_anchor_pose_ranges_and_sign_rule(ood):
    rng = np.random.default_rng(1)
    poses = [sample_anchor_pose(rng, ood) for _ in range(2000)]
    rot = np.array([p[0] for p in poses])
    trans = np.array([p[1] for p in poses])
    assert np.all(np.abs(rot) <= np.pi / 3)
    assert np.all(np.sign(trans[:, 0]) == np.where(rot >= 0, 1, -1))
    assert np.all((trans[:, 1] >= -10) & (trans[:, 1] <= 0))
    lo, hi = (5, 10) if ood else (0, 5)
    assert np.all((np.abs(trans[:, 0]) >= lo) & (np.abs(trans[:, 0]) <= hi))
    if ood:
        assert np.all((trans[:, 2] >= 1) & (trans[:, 2] <= 5))
    else:
        assert np.all(trans[:, 2] == 0)
    assert rot.min() < -0.9 and rot.max() > 0.9  # the whole range is used


def test_paper_dataset_sizes():
    assert TASKS["hangproccloth-simple"].sizes == {"train": 16, "val": 40, "unseen": 40, "ood": 40}
    assert TASKS["hangproccloth-unimodal"].sizes == {"train": 64, "val": 40, "unseen": 40, "ood": 40}
    assert TASKS["hangproccloth-multimodal"].demos_per_cloth == 2
    assert TASKS["hangbag"].sizes == {"train": 16, "val": 40, "unseen": 40, "ood": 40}


def test_seeds_reproducible_and_distinct():
    task, split = get_task("hangproccloth-unimodal"), get_split("train")
    a, b = episode_params(task, split, 3), episode_params(task, split, 3)
    assert a.cloth_params == b.cloth_params and a.rot_z == b.rot_z and np.array_equal(a.trans, b.trans)
    others = [episode_params(task, split, 4), episode_params(task, get_split("unseen"), 3), episode_params(task, split, 3, 1)]
    for other in others:
        assert other.rot_z != a.rot_z and other.cloth_params != a.cloth_params


def test_simple_task_keeps_the_fixed_cloth_and_ood_split_is_ood():
    params = episode_params(get_task("hangproccloth-simple"), get_split("ood"), 0)
    assert params.cloth_params["holes"] == [{"x0": 8, "x1": 16, "y0": 9, "y1": 13}]
    assert 5 <= abs(params.trans[0]) <= 10 and 1 <= params.trans[2] <= 5


def test_unknown_task_and_split():
    with pytest.raises(UsageError, match="unknown task 'hangcloth'"):
        get_task("hangcloth")
    with pytest.raises(UsageError, match="unknown split 'test'; expected one of train, val, unseen, ood"):
        get_split("test")


@pytest.mark.parametrize("task", list(TASKS))
def test_val_split_never_repeats_a_test_episode(task):
    """Every choice is made on `val`: its anchor poses and cloths are drawn under a seed of its own, so none equals
    an unseen or ood episode at any index the table scores (0-199), nor a training one."""
    spec = get_task(task)
    key = lambda p: (round(p.rot_z, 12), tuple(np.round(p.trans, 12)))
    val = {key(episode_params(spec, get_split("val"), i)) for i in range(200)}
    assert len(val) == 200
    for other in ("train", "unseen", "ood"):
        assert not val & {key(episode_params(spec, get_split(other), i)) for i in range(200)}
    assert not get_split("val").ood and get_split("val").seed not in {get_split(s).seed for s in ("train", "unseen", "ood")}
