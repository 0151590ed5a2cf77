from pathlib import Path

import pytest

OFFICIAL = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "tax3d-official" / "hangproccloth-simple"


@pytest.fixture(scope="session")
def official_dir() -> Path:
    if not OFFICIAL.is_dir():
        pytest.skip(f"official demonstrations not found at {OFFICIAL}")
    return OFFICIAL


@pytest.fixture(scope="session")
def generated(tmp_path_factory):
    """One real, full-length expert episode of HangProcCloth-simple (about 10 s), shared by the tests that need one."""
    from tax3d.sim.generate import Args, generate

    out = tmp_path_factory.mktemp("demos")
    stats = generate(Args(task="hangproccloth-simple", split="unseen", num=1, out=out), progress=False)
    return out, stats


@pytest.fixture
def demos(tmp_path):
    """Two small synthetic demonstrations (tests.test_model_api.synthetic_demo) in a folder."""
    from tax3d.data.format import save_demo
    from tests.test_model_api import synthetic_demo

    folder = tmp_path / "demos"
    folder.mkdir()
    for i in range(2):
        save_demo(folder / f"demo_{i}.npz", synthetic_demo(i))
    return folder
