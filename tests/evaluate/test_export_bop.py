"""``write_bop``: a run as a BOP dataset, read back by a checker written from BOP's documentation."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from deckpose.evaluate.export_bop import write_bop
from deckpose.evaluate.export_images import ImageMode
from scipy.spatial.transform import Rotation

from deckpose.camera import preset
from deckpose.camera_info import write_camera_info
from deckpose.errors import InputDataError
from deckpose.layout import DeckLayout
from deckpose.run_folder import run_paths
from tests.evaluate.bop_format_check import project_bop, read_bop_dataset
from tests.evaluate.fake_run import make_fake_run
from tests.tolerances import PROJECTION_PX, ROUNDOFF


@pytest.fixture(scope="module")
def fake_run(tmp_path_factory) -> Path:
    return make_fake_run(tmp_path_factory.mktemp("bop") / "run", n_per_cell=2)


@pytest.fixture(scope="module")
def bop(fake_run: Path, tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("bop_out") / "bop"
    write_bop(run_paths(fake_run), out)
    return out


def _truth(run: Path) -> tuple[pd.DataFrame, pd.DataFrame]:
    frames = pd.read_parquet(run / "frames.parquet").set_index("frame_id")
    beacons = pd.read_parquet(run / "beacons.parquet").sort_values(["frame_id", "beacon_id"])
    return frames, beacons


def test_the_export_reads_back_as_a_bop_dataset(bop: Path, fake_run: Path) -> None:
    ds = read_bop_dataset(bop)
    frames, _ = _truth(fake_run)
    assert set(ds.models) == {1}
    # one scene per camera, every frame once, im_id = frame_id
    im_ids = sorted(i for s in ds.scenes.values() for i in s.gt)
    assert im_ids == sorted(frames.index)
    assert [k[0] for k in ds.scenes] == ["test"] * 2
    for scene in ds.scenes.values():
        cams = {frames.loc[i, "camera"] for i in scene.gt}
        assert len(cams) == 1
        for im_id, img in scene.images.items():
            assert img.parent.name == "rgb" and img.is_symlink()
            assert img.resolve() == (fake_run / frames.loc[im_id, "image"]).resolve()
    info = ds.models_info[1]
    half_mm = 1.4 * DeckLayout().radius_m * 1000.0  # the default plate, 1.4 x the ring radius
    assert info["size_x"] == pytest.approx(2 * half_mm) and info["size_z"] == 0.0
    assert info["diameter"] == pytest.approx(2 * np.sqrt(2) * half_mm)


def test_poses_are_the_truth_in_millimetres(bop: Path, fake_run: Path) -> None:
    # computed here from the frames table alone: T_cam_from_deck = T_world_from_cam^-1 T_world_from_deck
    ds = read_bop_dataset(bop)
    frames, _ = _truth(fake_run)
    for scene in ds.scenes.values():
        for im_id, (inst,) in scene.gt.items():
            f = frames.loc[im_id]
            R_wd = Rotation.from_euler("ZYX", [f.yaw_deg, f.pitch_deg, f.roll_deg], degrees=True).as_matrix()
            t_wd = np.array([f.surge_m, f.sway_m, f.heave_m])
            R_wc = np.array([[f[f"R_world_from_cam_{i}{j}"] for j in range(3)] for i in range(3)])
            c_w = np.array([f.cam_x_m, f.cam_y_m, f.cam_z_m])
            np.testing.assert_allclose(inst["R"], R_wc.T @ R_wd, atol=ROUNDOFF)
            np.testing.assert_allclose(inst["t_mm"].ravel(), 1000.0 * R_wc.T @ (t_wd - c_w), atol=1e-9)


def test_the_models_beacons_project_onto_the_truth_pixels(bop: Path, fake_run: Path) -> None:
    ds = read_bop_dataset(bop)
    _, beacons = _truth(fake_run)
    n = DeckLayout().n_beacons
    pts = ds.models[1].pts_mm[:n]  # vertex i is beacon id i
    np.testing.assert_allclose(pts, DeckLayout().positions_deck_m() * 1000.0, atol=0)
    worst = 0.0
    for scene in ds.scenes.values():
        for im_id, (inst,) in scene.gt.items():
            uv = project_bop(pts, scene.camera[im_id]["cam_K"], inst["R"], inst["t_mm"])
            truth = beacons[beacons.frame_id == im_id][["u_px", "v_px"]].to_numpy()
            worst = max(worst, float(np.abs(uv - truth).max()))
    assert worst < PROJECTION_PX


def test_the_model_is_one_flat_surface_with_coloured_beacons(bop: Path) -> None:
    import trimesh

    mesh = trimesh.load(bop / "models" / "obj_000001.ply", process=False)
    assert isinstance(mesh, trimesh.Trimesh)
    side = 2 * 1.4 * DeckLayout().radius_m * 1000.0
    assert mesh.area == pytest.approx(side**2, rel=1e-9)  # no overlap, no hole
    assert np.all(mesh.face_normals[:, 2] > 0.999)
    colours = mesh.visual.vertex_colors[:, :3]
    lay = DeckLayout()
    np.testing.assert_array_equal(colours[0], np.round(np.array(lay.bow_rgb) * 255))
    np.testing.assert_array_equal(colours[1], np.round(np.array(lay.beacon_rgb) * 255))


def test_copies_instead_of_links(fake_run: Path, tmp_path: Path) -> None:
    out = write_bop(run_paths(fake_run), tmp_path / "bop", images=ImageMode.COPY)
    imgs = sorted((out.root / "test").glob("*/rgb/*.png"))
    assert len(imgs) == out.n_images and not any(p.is_symlink() for p in imgs)
    assert imgs[0].read_bytes() == (fake_run / "images" / imgs[0].name).read_bytes()


def test_a_distorted_camera_is_refused(fake_run: Path, tmp_path: Path) -> None:
    run = tmp_path / "run"
    shutil.copytree(fake_run, run)
    cam = preset("4mp").with_size(578, 434)
    write_camera_info(type(cam)(cam.width_px, cam.height_px, cam.K, np.array([-0.1, 0.01, 0, 0, 0]),
                                cam.name), run / "cameras" / "4mp-small.yaml")
    with pytest.raises(InputDataError, match="lens distortion.*4mp-small.*|4mp-small.*lens distortion"):
        write_bop(run_paths(run), tmp_path / "bop")
    assert not (tmp_path / "bop").exists()  # refused before anything is written


def test_missing_images_are_refused_before_writing(fake_run: Path, tmp_path: Path) -> None:
    run = tmp_path / "run"
    shutil.copytree(fake_run, run)
    (run / "images" / "000003.png").unlink()
    with pytest.raises(InputDataError, match="1 of .* images are missing.*000003.png"):
        write_bop(run_paths(run), tmp_path / "bop")
    assert not (tmp_path / "bop").exists()
