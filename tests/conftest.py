from pathlib import Path

import pytest

#: The project's shared folder sits beside the repository (CI clones main with shared/ beside it).
SHARED = Path(__file__).resolve().parents[1].parent / "shared"


@pytest.fixture
def shared_dir() -> Path:
    if not SHARED.is_dir():
        pytest.skip(f"shared folder not found at {SHARED}")
    return SHARED
