"""Fixtures for the motion tests."""

from pathlib import Path

import pytest

from tests.motion.reference import THESIS_CSV


@pytest.fixture
def thesis_csv() -> Path:
    """The thesis's motion CSV; skips when the shared/ folder is not beside the repository."""
    if not THESIS_CSV.is_file():
        pytest.skip(f"reference file {THESIS_CSV} absent (the shared/ folder must sit beside the repository)")
    return THESIS_CSV
