from pathlib import Path

import pytest
from hypothesis import settings

# Hypothesis's per-example deadline (200 ms) is a timing check, and timings here are not the
# tests' subject: on a loaded 2-core machine, or beside another pytest worker, a 1 ms example
# once took 565 ms and failed as "flaky". Correctness is what these tests check.
settings.register_profile("deckpose", deadline=None)
settings.load_profile("deckpose")

#: The project's shared folder sits beside the repository (CI clones main with shared/ beside it).
SHARED = Path(__file__).resolve().parents[1].parent / "shared"


@pytest.fixture
def shared_dir() -> Path:
    if not SHARED.is_dir():
        pytest.skip(f"shared folder not found at {SHARED}")
    return SHARED
