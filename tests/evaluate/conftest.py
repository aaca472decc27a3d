"""Fixtures shared by the evaluation tests."""

import pytest

from deckpose.cli import main
from tests.evaluate.fake_run import make_fake_run


@pytest.fixture(scope="module")
def evaluated_run(tmp_path_factory):
    """A fake run estimated with ``thesis`` and evaluated (MCAP log with a 256 px preview)."""
    root = make_fake_run(tmp_path_factory.mktemp("evaluated") / "run")
    assert main(["estimate", "--run", str(root), "--detector", "fake", "--method", "thesis"]) == 0
    assert main(["evaluate", str(root), "--preview-px", "256"]) == 0
    return root
