"""Fixtures shared by the evaluation tests."""

import shutil

import pytest
from deckpose.evaluate.run import write_log

from deckpose import run_folder as rl
from deckpose.cli import main
from deckpose.tables import write_table
from deckpose.tracking.config import TrackConfig
from deckpose.tracking.run import track_table
from tests.evaluate.fake_run import make_fake_run


@pytest.fixture(scope="module")
def evaluated_run(tmp_path_factory):
    """A fake run estimated with ``thesis`` and evaluated (MCAP log with a 256 px preview)."""
    root = make_fake_run(tmp_path_factory.mktemp("evaluated") / "run")
    assert main(["estimate", "--run", str(root), "--detector", "fake", "--method", "thesis"]) == 0
    assert main(["evaluate", str(root), "--preview-px", "256"]) == 0
    return root


#: Horizons of the tracked run's predictions, s: one and two frame intervals.
TRACK_HORIZONS_S = (0.1, 0.2)


@pytest.fixture(scope="module")
def tracked_run(evaluated_run, tmp_path_factory):
    """The evaluated fake run (3 frames 0.1 s apart per camera and height) with a track of its thesis estimates."""
    root = tmp_path_factory.mktemp("tracked") / "run"
    shutil.copytree(evaluated_run, root)
    run = rl.run_paths(root)
    frames = rl.read_frames(run)
    tracks, preds = track_table(frames, rl.read_estimates(run, "fake", "thesis"),
                                TrackConfig(horizons_s=TRACK_HORIZONS_S))
    run.tracks_dir.mkdir()
    write_table(tracks, run.tracks("fake", "thesis", "wave-bank"), "tracks")
    write_table(preds, run.track_predictions("fake", "thesis", "wave-bank"), "track predictions")
    write_log(run)  # the log and its layout
    return root
