from pathlib import Path

import pytest

OFFICIAL = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "tax3d-official" / "hangproccloth-simple"


@pytest.fixture(scope="session")
def official_dir() -> Path:
    if not OFFICIAL.is_dir():
        pytest.skip(f"official demonstrations not found at {OFFICIAL}")
    return OFFICIAL
