"""``read_export_frames``: a run's frames and truth for the exporters, and its refusals."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from deckpose.evaluate.export_frames import deck_half_size_m, read_export_frames

from deckpose.errors import InputDataError
from deckpose.layout import DeckLayout
from deckpose.run_folder import run_paths
from tests.evaluate.fake_run import make_fake_run


@pytest.fixture(scope="module")
def fake_run(tmp_path_factory) -> Path:
    return make_fake_run(tmp_path_factory.mktemp("export_frames") / "run", n_per_cell=1)


def test_frames_in_order_with_their_truth(fake_run: Path) -> None:
    f = read_export_frames(run_paths(fake_run))
    assert f.n_frames == 4 and list(f.frame_id) == [0, 1, 2, 3]
    assert f.points_px.shape == (4, 13, 2) and f.T_cam_from_deck.shape == (4, 4, 4)
    assert f.visible.all() and not f.T_cam_from_deck.flags.writeable
    assert f.image_relpath[2] == "images/000002.png" and f.image_path[2].is_file()
    assert deck_half_size_m(f.manifest, f.layout) == pytest.approx(14.0)  # no config: the default


def test_a_beacons_table_missing_rows_is_refused(fake_run: Path, tmp_path: Path) -> None:
    run = tmp_path / "run"
    shutil.copytree(fake_run, run)
    b = pd.read_parquet(run / "beacons.parquet")
    b[~((b.frame_id == 1) & (b.beacon_id == 4))].to_parquet(run / "beacons.parquet", index=False)
    with pytest.raises(InputDataError, match="one row per frame and beacon id 0..12"):
        read_export_frames(run_paths(run))


def test_a_frame_with_an_unknown_camera_is_refused(fake_run: Path, tmp_path: Path) -> None:
    run = tmp_path / "run"
    shutil.copytree(fake_run, run)
    fr = pd.read_parquet(run / "frames.parquet")
    fr.loc[0, "camera"] = "nosuch"
    fr.to_parquet(run / "frames.parquet", index=False)
    with pytest.raises(InputDataError, match="nosuch.yaml is missing"):
        read_export_frames(run_paths(run))


def test_poses_match_the_layout_projection(fake_run: Path) -> None:
    f = read_export_frames(run_paths(fake_run))
    P = DeckLayout().positions_deck_m()
    for i in range(f.n_frames):
        T = f.T_cam_from_deck[i]
        uv = f.cameras[f.camera[i]].project(P @ T[:3, :3].T + T[:3, 3])
        np.testing.assert_allclose(uv, f.points_px[i], atol=1e-9)
